"""Small hand-analysable mechanisms for the index, statics and dynamics tests.

* :class:`Iso6` -- six SPS legs in three orthogonal pairs: the legs of pair ``k`` run along
  ``e_k`` and meet the platform at ``+-r e_j`` (``j = k + 1 mod 3``). At the home pose every
  unit actuation wrench, with moments divided by ``r``, is ``(e_k, +-e_j x e_k)``: the six are
  orthogonal with equal norms, so the Jacobian made homogeneous with ``L = r`` is isotropic
  (condition number 1). Locking all legs but one, the platform twist is proportional to that
  leg's own scaled wrench, which moves its anchor exactly along the leg: every input and
  output transmission index is 1. ``extra_leg=True`` adds a seventh SPS leg along ``e_x``
  through ``P`` (redundant actuation).
* :class:`Tsai3` -- a translational 3-UPU (Tsai): three orthogonal actuated UPU legs whose
  base and platform universal-joint axes are parallel; each leg's constraint is a couple
  about its own axis, so the platform only translates. With the legs along x, y, z every
  transmission index is 1 and the Jacobian is the identity.
"""

from __future__ import annotations

import numpy as np

from parasynth.model.legs import SPS, UPU
from parasynth.model.mechanism import Mechanism
from parasynth.model.spatial import euler_rate_map, euler_to_matrix


class Iso6(Mechanism):
    name = "iso6"
    task_coordinates = ("x", "y", "z", "a", "b", "c")
    angular_coordinates = frozenset({"a", "b", "c"})

    def __init__(self, r: float = 0.2, ell: float = 0.8, length_scale: float | None = None,
                 extra_leg: bool = False):
        e = np.eye(3)
        legs = []
        for k in range(3):
            j = (k + 1) % 3
            for s in (1.0, -1.0):
                A = s * r * e[j]
                legs.append(SPS(f"L{len(legs) + 1}", base=A - ell * e[k], platform=A))
        if extra_leg:
            legs.append(SPS("L7", base=-ell * e[0], platform=np.zeros(3)))
        self.r, self.ell = r, ell
        super().__init__(None, legs, np.zeros(6), length_scale=r if length_scale is None else length_scale)

    def _pose(self, X):
        return X[:, :3].copy(), euler_to_matrix("xyz", X[:, 3:])

    def _twist_map(self, X):
        T = np.zeros((X.shape[0], 6, 6))
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = 1.0
        T[:, 3:, 3:] = euler_rate_map("xyz", X[:, 3:])
        return T


class Tsai3(Mechanism):
    name = "tsai3"
    task_coordinates = ("x", "y", "z")
    angular_coordinates = frozenset()

    def __init__(self, ell: float = 0.6, r: float = 0.1):
        e = np.eye(3)
        legs = []
        for k in range(3):
            j, a = (k + 1) % 3, e[(k + 2) % 3]
            A = r * e[j]
            legs.append(UPU(f"L{k + 1}", base=A - ell * e[k], platform=A, u_axis=a, u_platform_axis=a,
                            passive=False))
        super().__init__(None, legs, np.zeros(3), length_scale=ell)

    def _pose(self, X):
        return X.copy(), np.broadcast_to(np.eye(3), (X.shape[0], 3, 3)).copy()

    def _twist_map(self, X):
        T = np.zeros((X.shape[0], 6, 3))
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = 1.0
        return T
