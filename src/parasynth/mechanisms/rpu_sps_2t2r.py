"""2-RPU&2-SPS 2T2R manipulator (An, Li, Wang & Ge, 2018): model ``"2rpu_2sps"``.

Frames (paper Section 2, Figure 2): base frame O-xyz at the centre of the base quadrilateral,
x towards B2, y towards B3, z normal to the base; platform frame A-uvw likewise (u towards A2,
v towards A3). Legs 1 and 3 are SPS legs on the y axis, legs 2 and 4 RPU legs on the x axis
whose revolute axes and the leg-side universal-joint axes are parallel to y and whose
platform-side universal-joint axes are parallel to u. Anchors (eq. (6)):
a_{10} = a1 (0,-1,0), a_{20} = a2 (1,0,0), a_{30} = a3 (0,1,0), a_{40} = a4 (-1,0,0) and the same
for b_i. Orientation: eq. (1), R = Ry(theta) Rz(phi) Rx(psi).

The RPU legs force phi = 0 and y = 0 (eq. (9)); the mechanism then has the four freedoms
x, z, psi, theta (screw analysis: the two RPU legs impose a force along y and a couple normal
to y and u; the SPS legs impose nothing). The paper's eq. (8) additionally dots the SPS
closure with c_i = R (1,0,0), which is not a property of an SPS leg; with (7) and (9) it yields
eq. (10), x = z tan(theta). That extra relation is what Tables 1 and 2 use.

Two parametrisations are offered:

* ``coupled=True`` (default, reproduces Tables 1 and 2): task coordinates (z, psi, theta),
  x = z tan(theta) a dependent coordinate. Four actuators over-determine three coordinates, so
  forward kinematics is a consistency-checked least-squares solve.
* ``coupled=False``: task coordinates (x, z, psi, theta), the mechanism's true freedoms.

Actuators: leg lengths q1..q4 = |A_i - B_i| (eq. (11)), m.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..constraints import ActuatorRange, CoordinateRange, LegInterference
from ..legs import RPU, SPS
from ..mechanism import Mechanism, check_length
from ..spatial import euler_rate_map, euler_to_matrix

__all__ = ["RPU2SPS2Params", "RPU2SPS2"]


@dataclass(frozen=True)
class RPU2SPS2Params:
    """Parameters (m). Defaults: Section 4.3 of the paper (a1 = a3 = 150 mm,
    a2 = a4 = 75 mm, b1 = b3 = 550 mm, b2 = b4 = 350 mm)."""

    #: Quantity kind of each field, for unit-bearing input (YAML, CLI).
    UNITS: ClassVar[dict] = {**{k: "length" for k in ("a1", "a2", "a3", "a4", "b1", "b2", "b3", "b4",
                                                      "q_min", "q_max", "leg_diameter")},
                             "psi_max": "angle", "theta_max": "angle", "coupled": None}


    a1: float = 0.150
    a2: float = 0.075
    a3: float = 0.150
    a4: float = 0.075
    b1: float = 0.550
    b2: float = 0.350
    b3: float = 0.550
    b4: float = 0.350
    coupled: bool = True
    # Limits, Section 6.2: 700 <= q_i <= 1000 mm, -30 <= psi <= 30 deg, -45 <= theta <= 45 deg.
    q_min: float = 0.700
    q_max: float = 1.000
    psi_max: float = float(np.deg2rad(30.0))
    theta_max: float = float(np.deg2rad(45.0))
    #: Leg diameter for interference (not stated in the paper).
    leg_diameter: float = 0.030

    def __post_init__(self):
        for k in ("q_min", "q_max", "psi_max", "theta_max", "leg_diameter"):
            object.__setattr__(self, k, check_length(f"2rpu_2sps.{k}", getattr(self, k)))
        if not self.q_min < self.q_max:
            raise ValueError(f"2rpu_2sps.q_min must be < q_max, got {self.q_min} >= {self.q_max}")
        for k in ("a1", "a2", "a3", "a4", "b1", "b2", "b3", "b4"):
            object.__setattr__(self, k, check_length(f"2rpu_2sps.{k}", getattr(self, k)))
        if not isinstance(self.coupled, (bool, np.bool_)):
            raise ValueError(f"2rpu_2sps.coupled must be true or false, got {self.coupled!r}")


class RPU2SPS2(Mechanism):
    name = "2rpu_2sps"
    paper = "An, Li, Wang, Ge (2018), Kinematics and transmission performance analyses of a 2T2R type 4-DOF spatial parallel manipulator"
    Params = RPU2SPS2Params

    def __init__(self, params: RPU2SPS2Params | None = None):
        params = params or RPU2SPS2Params()
        self.params = params
        P = params
        y, x = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])
        legs = [
            SPS("L1", base=-P.b1 * y, platform=-P.a1 * y),
            RPU("L2", base=P.b2 * x, platform=P.a2 * x, r_axis=y, u_platform_axis=x),
            SPS("L3", base=P.b3 * y, platform=P.a3 * y),
            RPU("L4", base=-P.b4 * x, platform=-P.a4 * x, r_axis=y, u_platform_axis=x),
        ]
        if P.coupled:
            self.task_coordinates = ("z", "psi", "theta")
            home = [0.75, 0.0, np.deg2rad(15.0)]
        else:
            self.task_coordinates = ("x", "z", "psi", "theta")
            home = [0.75 * np.tan(np.deg2rad(15.0)), 0.75, 0.0, np.deg2rad(15.0)]
        self.angular_coordinates = frozenset({"psi", "theta"})
        super().__init__(params, legs, home, length_scale=0.5 * (P.b1 + P.b2))

    def default_ranges(self) -> dict:
        """A task box covering the paper's workspace (Section 6.2) with margin, SI."""
        r = {"z": (0.55, 1.00), "psi": (-self.params.psi_max, self.params.psi_max),
             "theta": (-self.params.theta_max, self.params.theta_max)}
        if not self.params.coupled:
            r = {"x": (-0.6, 0.6), **r}
        return r

    def _split(self, X):
        if self.params.coupled:
            z, psi, th = X[:, 0], X[:, 1], X[:, 2]
            x = z * np.tan(th)
        else:
            x, z, psi, th = X.T
        return x, z, psi, th

    def _pose(self, X):
        x, z, psi, th = self._split(X)
        p = np.stack([x, np.zeros_like(x), z], axis=-1)
        R = euler_to_matrix("yzx", np.stack([th, np.zeros_like(th), psi], -1))
        return p, R

    def pose_valid(self, X):
        ok = np.all(np.isfinite(X), axis=-1)
        th = np.where(ok, X[:, self.task_coordinates.index("theta")], 0.0)
        return ok & (np.abs(np.cos(th)) > 1e-9)

    def _twist_map(self, X):
        x, z, psi, th = self._split(X)
        N = X.shape[0]
        E = euler_rate_map("yzx", np.stack([th, np.zeros_like(th), psi], -1))  # (N,3,3): theta, phi, psi
        T = np.zeros((N, 6, self.n_task))
        if self.params.coupled:
            sec2 = 1.0 / np.cos(th) ** 2
            T[:, 0, 0] = np.tan(th)  # dx/dz
            T[:, 2, 0] = 1.0  # dz/dz
            T[:, 0, 2] = z * sec2  # dx/dtheta
            T[:, 3:, 1] = E[:, :, 2]  # psi
            T[:, 3:, 2] = E[:, :, 0]  # theta
        else:
            T[:, 0, 0] = 1.0
            T[:, 2, 1] = 1.0
            T[:, 3:, 2] = E[:, :, 2]
            T[:, 3:, 3] = E[:, :, 0]
        return T

    def build_constraints(self):
        """Section 6.1-6.2: leg strokes (eq. (33)) and the angle limits of (34)-(35), read as
        limits on the platform angles psi and theta (the paper calls them joint angles but
        gives one range for each symbol); leg interference with ``leg_diameter``."""
        P = self.params
        i_psi, i_th = self.task_coordinates.index("psi"), self.task_coordinates.index("theta")
        return [
            ActuatorRange("stroke", lo=P.q_min, hi=P.q_max, doc="q_min <= q_i <= q_max, eq. (33)"),
            CoordinateRange("psi_range", unit="rad", index=i_psi, lo=-P.psi_max, hi=P.psi_max,
                            doc="|psi| <= psi_max, eq. (35)"),
            CoordinateRange("theta_range", unit="rad", index=i_th, lo=-P.theta_max, hi=P.theta_max,
                            doc="|theta| <= theta_max, eq. (34)"),
            LegInterference("interference", diameter=P.leg_diameter,
                            doc="distance between leg centre lines >= leg_diameter"),
        ]

    def x_of(self, X) -> np.ndarray:
        """The platform centre's x (m) for poses X (dependent in the coupled model)."""
        Xa, _ = self._poses(X)
        return self._split(Xa)[0]
