"""The parasitic coordinates of a structure (``task.solve``) by the compiled solve
(``parasynth.engine.solved_unknowns``) against the NumPy Gauss-Newton (``solved_unknowns``), and
the measures that evaluate the NumPy model at workspace points taking them (the maximum actuator
force, ``objectives._points``): the same values to the solve's rounding."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from parasynth import engine
from parasynth.measures import objectives
from parasynth.model.chains import ChainLeg

from _enumerated import enumerated, per_motion

pytestmark = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not available")


def _solved(motion):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = [s.mechanism() for s in enumerated(motion)]
    return [m for m in out if getattr(m.description.task, "solve", None) is not None]


@pytest.mark.parametrize("motion", per_motion(["1T2R", "3T0R"]))
def test_compiled_unknowns_are_the_numpy_solves(motion):
    mechs = _solved(motion)
    assert mechs, f"no {motion} structure with a parasitic motion"
    rng = np.random.default_rng(7)
    compiled = 0
    for m in mechs:
        lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
        X = np.vstack([m.home, m.home + 0.2 * (hi - lo) * rng.uniform(-0.5, 0.5, size=(300, len(lo)))])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = engine.solved_unknowns(m, X)
        if any(isinstance(lg, ChainLeg) for lg in m._solve_legs):  # solved on a chain limb's closure: NumPy only
            assert out is None, m.name
            continue
        compiled += 1
        ok, U = out
        Un = m.solved_unknowns(X)
        conv = np.isfinite(Un).all(axis=1)
        assert conv.sum() > 100 and conv[0]
        assert np.array_equal(ok[conv], np.ones(conv.sum(), bool)), m.name  # valid where NumPy converged
        assert np.allclose(U[conv], Un[conv], rtol=0, atol=1e-12), (m.name, np.abs(U[conv] - Un[conv]).max())
        assert engine.solved_unknowns(m, X, engine="numpy") is None  # the NumPy engine answers with its own solve
    assert compiled >= 1


@pytest.mark.parametrize("motion", per_motion(["1T2R"]))
def test_the_force_over_the_workspace_with_compiled_unknowns_is_the_numpy_one(motion, monkeypatch):
    real = objectives.solve_compiled
    kw = dict(mass=20.0, com=(0.0, 0.0, -0.15), force=(300.0, 300.0, -500.0), max_points=128, n=1024,
              method="sobol", seed=0)
    from parasynth.mechanisms.description import mechanism as described

    solves = []
    real_solve = described.gauss_newton

    def counted(fun, X, *a, **k):
        solves.append(len(X))
        return real_solve(fun, X, *a, **k)

    monkeypatch.setattr(described, "gauss_newton", counted)
    for m in _solved(motion)[:4]:
        ranges = m.default_ranges()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            objectives.max_actuator_force(m, ranges=ranges, **kw)  # the compiled programs built and checked once
            objectives._CACHE.clear()
            m._solve_cache = None
            solves.clear()
            fast = objectives.max_actuator_force(m, ranges=ranges, **kw)
            assert max(solves, default=0) <= 1  # the compiled unknowns were taken: no NumPy solve at the points
            monkeypatch.setattr(objectives, "solve_compiled", lambda *a: None)
            objectives._CACHE.clear()
            m._solve_cache = None
            solves.clear()
            slow = objectives.max_actuator_force(m, ranges=ranges, **kw)
            assert max(solves) > 1  # the NumPy solve at the points
            monkeypatch.setattr(objectives, "solve_compiled", real)
        assert slow > 0 and fast == pytest.approx(slow, rel=1e-10, abs=0), m.name


@pytest.mark.parametrize("motion", per_motion(["1T2R"]))
def test_unknowns_given_to_the_model_are_checked(motion):
    m = _solved(motion)[0]
    X = np.atleast_2d(m.home)
    U = m.solved_unknowns(X)
    m.use_solved_unknowns(X, U)
    assert np.array_equal(m.solved_unknowns(X), U)
    with pytest.raises(ValueError, match="shape"):
        m.use_solved_unknowns(X, U[:, :1])
    with pytest.raises(ValueError, match="not finite"):
        m.use_solved_unknowns(X, np.full_like(U, np.nan))


@pytest.mark.parametrize("motion", per_motion(["1T2R"]))
def test_offered_unknowns_are_solved_only_when_asked_and_refused_when_not_a_solution(motion):
    m = _solved(motion)[0]
    X = np.atleast_2d(m.home)
    U = m.solved_unknowns(X)
    asked = []
    m.use_solved_unknowns(X, lambda: asked.append(1) or U + 0.0)
    assert not asked  # not solved until the NumPy model asks
    assert np.array_equal(m.solved_unknowns(X), U) and asked == [1]
    assert np.array_equal(m.solved_unknowns(X), U) and asked == [1]  # kept once computed
    m.use_solved_unknowns(X, lambda: np.full_like(U, np.nan))  # no solution offered: the NumPy solve
    assert np.array_equal(m.solved_unknowns(X), U)
