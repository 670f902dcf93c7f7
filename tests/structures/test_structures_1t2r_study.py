"""The shipped 1T2R structure study (studies/structures_1t2r.yaml): it searches the 3-RPS and the
3-PRS with the motion of the shipped closed-form models, and what else 1T2R gives with every
axis choice (three 3-UPU).

Independent values: the parasitic x, y of the study's 3-RPS at the shipped 3rps model's
dimensions against the closed form written here (x = a/2 (R11 - R22), y = -a R21, Tsai's; the
3rps.yaml header), and the sign of the study's force column unit (linear actuators: N)."""

from pathlib import Path

import numpy as np
import pytest

from parasynth.measures.display import quantity_unit
from parasynth.study import load_study
from parasynth.study.design import design_mechanism

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def study():
    return load_study(ROOT / "studies" / "structures_1t2r.yaml")


def test_the_study_searches_the_1t2r_structures(study):
    choices = next(v for v in study.variables if v.name == "structure").choices
    assert choices[:2] == ("3-RPS", "3-PRS") or list(choices[:2]) == ["3-RPS", "3-PRS"]
    assert sum(c.startswith("3-UPU") for c in choices) == 3 and len(choices) == 5
    assert study.structures.reference == "3-RPS"
    assert quantity_unit(study, "force_max").symbol == "N"  # RPS, PRS and UPU legs: linear actuators


def test_its_3rps_has_the_closed_form_parasitic_motion(study):
    a = 0.15  # the shipped 3rps model's platform radius
    m = design_mechanism(study, {"structure": "3-RPS", "base_radius": 0.3, "platform_radius": a, "height": 0.5,
                                 "q_min": 0.3})
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.uniform(0.45, 0.55, 20), rng.uniform(-0.3, 0.3, 20), rng.uniform(-0.3, 0.3, 20)])
    p, R = m.pose(X)
    ok = np.all(np.isfinite(p), axis=1)
    assert ok.sum() >= 15
    np.testing.assert_allclose(p[ok, 0], a / 2 * (R[ok, 0, 0] - R[ok, 1, 1]), atol=1e-9)
    np.testing.assert_allclose(p[ok, 1], -a * R[ok, 1, 0], atol=1e-9)
    np.testing.assert_allclose(p[ok, 2], X[ok, 0], atol=1e-12)
