"""The report's drawings of a design (study/view.py): rounded in one pass as element by element,
and a structure with parasitic coordinates drawn from the compiled solve as from the NumPy one."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from parasynth.study import load_study
from parasynth.study import view
from parasynth.study.problem import Problem

STUDIES = Path(__file__).resolve().parents[2] / "studies"


def _rounded_elementwise(a, digits=1):  # the earlier form, element by element
    a = np.round(np.asarray(a, dtype=float), digits)
    if a.ndim == 0:
        return float(a) if np.isfinite(a) else None
    return [_rounded_elementwise(x, digits) for x in a]


def test_rounded_in_one_pass_as_element_by_element():
    rng = np.random.default_rng(3)
    for shape in [(), (7,), (4, 3), (2, 5, 3)]:
        a = rng.normal(size=shape) * 10.0 ** rng.integers(-3, 5, size=shape)
        for digits in (0, 1, 3):
            assert view.rounded(a, digits) == _rounded_elementwise(a, digits)
    b = np.array([[1.25, np.nan], [np.inf, -0.05]])
    assert view.rounded(b) == _rounded_elementwise(b) == [[1.2, None], [None, -0.0]]
    assert view.rounded(np.float64(np.nan)) is None


def test_a_structure_drawn_from_the_compiled_solve_as_from_numpy(monkeypatch):
    """A 3-RPS of structures_1t2r (x, y and gamma solved from its legs): the drawing with the
    compiled solve's unknowns equals the one with the NumPy solve's to the drawing's precision
    (0.1 mm)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        study = load_study(STUDIES / "structures_1t2r.yaml")
        problem = Problem(study)
        mech = problem.evaluator.build(problem.space.centre({"structure": "3-RPS"}))
        compiled = view.design_view(study, mech, 11, None, 0)
        calls = []
        monkeypatch.setattr(view, "solve_compiled", lambda *a, **k: calls.append(1))
        mech = problem.evaluator.build(problem.space.centre({"structure": "3-RPS"}))
        numpy = view.design_view(study, mech, 11, None, 0)
    assert calls  # the NumPy drawing did not take the compiled solve
    assert compiled is not None and compiled["n_feasible_samples"] > 100
    for key in ("anchors", "B", "A", "C", "cloud"):
        a, b = np.array(compiled[key], dtype=float), np.array(numpy[key], dtype=float)
        assert a.shape == b.shape and a.size > 0, key
        np.testing.assert_allclose(a, b, rtol=0, atol=0.1 + 1e-9, err_msg=key)  # at most one step of the rounding
    assert compiled["pose_text"] == numpy["pose_text"]
