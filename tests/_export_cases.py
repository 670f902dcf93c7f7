"""The mechanisms the export tests run on and their poses: every packaged mechanism and each
variant choice other than the default, and a user's description (``data/export_6rus.yaml``, the
one with RUS legs). Poses are drawn around the sampling centre of ``_support`` and kept where
the mechanism is feasible (constraints included), so that they lie inside the joint ranges the
export writes."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import parasynth
from parasynth.model.mechanism import EngineFallbackWarning

from _support import sample_poses, shipped_configs

USER_DESCRIPTION = str(Path(__file__).parent / "data" / "export_6rus.yaml")


CASES = shipped_configs() + [(USER_DESCRIPTION, {})]
IDS = [("user_6rus" if n == USER_DESCRIPTION else n) + "".join(f"-{v}" for v in p.values()) for n, p in CASES]


def load(name: str, params: dict):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)  # RUS legs run on NumPy, as documented
        return parasynth.load_mechanism(name, **params)


def feasible_poses(mech, n: int = 20, seed: int = 7) -> np.ndarray:
    """``n`` feasible poses near the sampling centre (deterministic)."""
    rng = np.random.default_rng(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        X = sample_poses(mech, rng, 40 * n)
        X = X[mech.is_feasible(X)]
    assert len(X) >= n, f"{mech.name}: only {len(X)} feasible poses of {40 * n} drawn"
    return X[:n]


def nearby_feasible(mech, X: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A feasible pose within 5 mm and 0.05 rad of ``X`` (per coordinate)."""
    step = np.array([0.05 if c in mech.angular_coordinates else 0.005 for c in mech.task_coordinates])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        for _ in range(50):
            X2 = X + step * rng.uniform(-1, 1, mech.n_task)
            if mech.is_feasible(X2):
                return X2
    raise AssertionError(f"{mech.name}: no feasible pose near {X.tolist()}")
