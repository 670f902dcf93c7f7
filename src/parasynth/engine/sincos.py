"""Vectorisable sine and cosine of one argument for the compiled pose stage.

Cephes ``sin.c``: the argument reduced by pi/4 in three parts, degree-6 polynomials; absolute
error <= ~2.2e-16, i.e. within an ulp or two of libm. A loop over poses calling it vectorises
(no libm call); arguments beyond :data:`_BIG_ANGLE` rad lose accuracy in the reduction, and the
callers recompute them with libm. The interpreter of :mod:`parasynth.engine.core` calls
:func:`_sincos`, and the pose loops generated per program (:mod:`parasynth.engine.posefn`)
embed this module's source, so that both compute the same bits.

This module imports only NumPy and numba (its source is pasted into the generated modules).
"""

import numpy as np
from numba import njit

_FOPI = 1.27323954473516268615
_DP1 = 7.85398125648498535156e-1
_DP2 = 3.77489470793079817668e-8
_DP3 = 2.69515142907905952645e-15
_S0, _S1, _S2, _S3, _S4, _S5 = (1.58962301576546568060e-10, -2.50507477628578072866e-8,
                                2.75573136213857245213e-6, -1.98412698295895385996e-4,
                                8.33333333332211858878e-3, -1.66666666666666307295e-1)
_C0, _C1, _C2, _C3, _C4, _C5 = (-1.13585365213876817300e-11, 2.08757008419747316778e-9,
                                -2.75573141792967388112e-7, 2.48015872888517045348e-5,
                                -1.38888888888730564116e-3, 4.16666666666665929218e-2)
_BIG_ANGLE = 1e6


@njit(nogil=True, error_model="numpy", fastmath=False, cache=True, inline="always")
def _sincos(x):
    # np.floor (float result): math.floor returns an integer, which keeps the loop scalar
    ax = abs(x)
    y = np.floor(ax * _FOPI)
    y = y + (y - 2.0 * np.floor(y * 0.5))  # next even octant
    j = y - 8.0 * np.floor(y * 0.125)  # octant mod 8: 0, 2, 4 or 6
    z = ((ax - y * _DP1) - y * _DP2) - y * _DP3
    zz = z * z
    ps = z + z * zz * (((((_S0 * zz + _S1) * zz + _S2) * zz + _S3) * zz + _S4) * zz + _S5)
    pc = 1.0 - 0.5 * zz + zz * zz * (((((_C0 * zz + _C1) * zz + _C2) * zz + _C3) * zz + _C4) * zz + _C5)
    swap = (j == 2.0) | (j == 6.0)
    s = pc if swap else ps
    c = ps if swap else pc
    s = -s if (j >= 4.0) != (x < 0.0) else s
    c = -c if (j == 2.0) | (j == 4.0) else c
    return s, c
