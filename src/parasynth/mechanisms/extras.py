"""Paper-specific extras of the packaged models that are not geometry.

The three paper models are defined by their packaged descriptions (``5pus_upu.yaml``,
``2rpu_2sps.yaml``, ``4ups_1rps.yaml``); what the papers add beyond the mechanism lives here
as small named functions:

* :func:`trajectory_eq13`: the 2021 paper's test trajectory (``5pus_upu``);
* :func:`grinding_u_angles`: the angles of the grinding robot's universal joints from its
  Table 2 parameters (``4ups_1rps``).

The grinding robot's inertias (Table 3) and its grinding trajectories are in
:mod:`parasynth.measures.dynamics` (``grinding_inertia``, ``GRINDING_INERTIA``,
``grinding_trajectory``, ``grinding_lift_trajectory``), next to the dynamics that use them.
"""

from __future__ import annotations

import numpy as np

__all__ = ["trajectory_eq13", "grinding_u_angles"]


def trajectory_eq13(t, attitude_follows_curve: bool = False):
    """The 2021 paper's test trajectory, eq. (13), as task coordinates of ``5pus_upu`` and
    their first and second time derivatives (each (N, 5), SI).

    ``u = pi/3 + pi t / 30`` (0 < t < 10 s), ``y = 50 cos u`` mm, ``z = -50 sin u`` mm,
    x = 0, beta = 0. The paper writes the curve parameter as alpha, the symbol of the platform
    attitude. With ``attitude_follows_curve=False`` (default) the platform keeps alpha = 0 and
    only its centre moves on the circle; with ``True`` the platform also tilts by alpha = u
    (60 to 120 deg), which is far outside any workspace of the prototype.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    w = np.pi / 30.0
    u = np.pi / 3.0 + w * t
    r = 0.050
    X = np.zeros((t.size, 5))
    Xd = np.zeros_like(X)
    Xdd = np.zeros_like(X)
    X[:, 1], X[:, 2] = r * np.cos(u), -r * np.sin(u)
    Xd[:, 1], Xd[:, 2] = -r * w * np.sin(u), -r * w * np.cos(u)
    Xdd[:, 1], Xdd[:, 2] = -r * w**2 * np.cos(u), r * w**2 * np.sin(u)
    if attitude_follows_curve:
        X[:, 3], Xd[:, 3] = u, w
    return X, Xd, Xdd


def grinding_u_angles(params) -> np.ndarray:
    """Angles (rad) of the universal joints U1..U4 of ``4ups_1rps`` on their circle (from +X
    towards +Z): the U1-U2 side (``mu1``) centred on ``u_phase``, then ``mu2``, ``mu1``
    (Table 2). ``params``: the model's ``Params`` (or anything with ``mu1``, ``mu2``,
    ``u_phase``). The description places the joints with the same angles."""
    a1 = params.u_phase - params.mu1 / 2
    return np.array([a1, a1 + params.mu1, a1 + params.mu1 + params.mu2, a1 + 2 * params.mu1 + params.mu2])
