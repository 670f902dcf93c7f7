"""Order statistics of a design's sample, without NumPy's general machinery.

``np.quantile`` of one quantile of a few thousand values costs ~60-90 us, nearly all of it
in the handling of axes, methods and weights; the partition it does costs ~15 us. A study
takes a quantile of the singularity margin over every design's workspace, so
:func:`quantile` computes NumPy's default ("linear") quantile of a 1-D float array with the
same operations in the same order (the same bits, checked in ``tests/common/test_stats.py``
against ``np.quantile``).
"""

from __future__ import annotations

import math

import numpy as np


def quantile(v: np.ndarray, q: float) -> float:
    """``float(np.quantile(v, q))`` (method "linear") of a non-empty 1-D float64 array ``v``
    without NaN, for ``0 <= q <= 1``; ``q == 0`` gives the least value (NumPy's "lower":
    the linear formula is NaN there when the next value is infinite). ``v`` is not modified."""
    n = v.shape[0]
    if n == 0:
        raise ValueError("quantile of an empty array")
    q = float(q)
    if not 0.0 <= q <= 1.0:
        raise ValueError(f"quantile must be in [0, 1], got {q!r}")
    if q == 0.0:
        return float(v.min())
    vi = (n - 1) * q  # NumPy's virtual index of the linear method: (n - 1) * q
    if vi >= n - 1:  # NumPy takes the last value twice, its weight vi - (-1)
        m = v.max()
        return float(m - (m - m) * (1.0 - (vi + 1.0)))
    lo = math.floor(vi)
    part = np.partition(v, (lo, lo + 1))
    a, b = part[lo], part[lo + 1]
    g = vi - lo
    d = b - a
    # NumPy's _lerp: a + d * g, or b - d * (1 - g) where g >= 0.5
    return float(b - d * (1.0 - g)) if g >= 0.5 else float(a + d * g)
