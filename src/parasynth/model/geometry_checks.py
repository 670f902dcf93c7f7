"""Degenerate geometry of a built mechanism: anchors that coincide, a mechanism singular at
every pose. Both are errors of ``parasynth validate`` (a study on such a mechanism would only
evaluate singular designs) and findings of ``parasynth analyze``."""

from __future__ import annotations

import numpy as np

from ..common.validation import numpy_reference
from ..common.units import UNIT_KINDS

_LENGTH = UNIT_KINDS["length"]

__all__ = ["degenerate_geometry", "SINGULAR_MARGIN"]

#: A singularity margin (dimensionless) below this is a singular pose.
SINGULAR_MARGIN = 1e-9


def _coincide(points: np.ndarray, scale: float) -> bool:
    P = np.asarray(points, dtype=float).reshape(len(points), -1)
    return len(P) > 1 and float(np.max(np.ptp(P, axis=0))) <= 1e-9 * max(scale, 1e-12)


def degenerate_geometry(mech, ranges=None, n: int = 256, seed: int = 0) -> list[str]:
    """Why ``mech`` is degenerate (empty list: it is not): its platform anchors, or its base
    anchors, all coincide; or it is singular (singularity margin below
    :data:`SINGULAR_MARGIN`) at its home pose and at every reachable pose of ``n`` samples of
    ``ranges`` (default the model's ranges). Evaluated with the NumPy reference engine:
    a check never waits for a cold compile."""
    out = []
    scale = float(getattr(mech, "length_scale", 1.0) or 1.0)
    legs = list(getattr(mech, "legs", ()))
    if len(legs) > 1:
        for side in ("platform", "base"):
            pts = [getattr(leg, side, None) for leg in legs]
            if all(p is not None for p in pts) and _coincide(np.array(pts), scale):
                out.append(f"degenerate geometry: the {len(legs)} {side} anchors coincide "
                           f"(at {np.round(np.asarray(pts[0], float) * _LENGTH.factor, 3).tolist()} {_LENGTH.display})")
    try:
        ranges = dict(ranges) if ranges else mech.default_ranges()
        task = list(mech.task_coordinates)
        rng = np.random.default_rng(seed)
        X = np.repeat(np.asarray(mech.home, float)[None, :], n, axis=0)
        for c, (lo, hi) in ranges.items():
            X[:, task.index(c)] = rng.uniform(lo, hi, n)
        X = np.vstack([np.asarray(mech.home, float)[None, :], X])
        with numpy_reference():  # a few hundred poses: never wait for a cold compile
            reach = np.asarray(mech.inverse_kinematics(X).reachable, bool)
            m = np.asarray(mech.singularity_margin(X[reach]), float) if reach.any() else None
        if m is not None:
            if np.all(~np.isfinite(m) | (m < SINGULAR_MARGIN)):
                out.append(f"degenerate geometry: the mechanism is singular at its home pose and at all "
                           f"{int(reach.sum())} reachable sampled poses (largest singularity margin "
                           f"{np.nanmax(m) if np.isfinite(m).any() else float('nan'):.2g}); no design of it "
                           f"can be evaluated meaningfully")
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        pass
    return out
