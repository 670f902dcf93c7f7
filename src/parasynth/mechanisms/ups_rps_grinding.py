"""4-UPS/1-RPS parallel grinding robot (Wang, Liang, Zhou, Yang & Wang, Symmetry 2022):
model ``"4ups_1rps"``.

Structure (Section 2 and 3): four driving U-P-S legs from the corners of a rectangular fixed
platform to four spheres evenly spaced on the disc-shaped moving platform, and one passive
constraining R-P-S branch whose revolute axis is parallel to the base Z axis at distance
``l_s0`` from the fixed-platform centre (Table 1: alpha_2 = -90 deg, so the prismatic joint
moves in the XY plane) and whose sphere is the moving-platform centre. Eq. (3): the platform
centre is ``(-d2 sin(theta1), d2 cos(theta1) - l_s0, 0)`` -- it stays in the plane Z = 0.

Orientation of the machine. Eq. (9) measures the sphere and universal-joint angles against
the Y axes of the moving and fixed frames (``phi_i^m = arccos(L_i . R n_mi / l_i)`` with
``n_mi = (0, 1, 0)``, likewise ``phi_i^s``), with limits of +-pi/4: the legs run along Y. The
fixed platform is therefore the plane Y = 0 of the base frame (universal joints at
``(Rs cos phi_i, 0, Rs sin phi_i)``), the moving platform is a disc in its local XZ plane with
normal y, and it moves away from the fixed platform (y > 0). Y is the vertical: the driving
legs carry gravity (Section 4.3) while the constant grinding force along Z is taken by the
constraining branch -- the paper's force decoupling.

Task coordinates: (x, y, alpha, beta, gamma): the platform centre in the plane Z = 0 and the
z-y-z Euler angles of eq. (2), R = Rz(alpha) Ry(beta) Rz(gamma). (The z-y-z angles are
degenerate at beta = 0, where only alpha + gamma is defined: Jacobian columns for alpha and
gamma coincide there. This is a property of the paper's convention, not of the mechanism.)

Screw analysis: the RPS branch imposes one constraint, a force along Z through the platform
centre, leaving five freedoms (2T3R). Four driving legs cannot control five freedoms: the
mechanism is under-actuated by one (``mobility().controlled`` is False); the paper's
constant-force actuator and workpiece contact are what close the loop in operation. Forward
kinematics therefore needs one coordinate fixed (``fixed={"gamma": ...}``), and static or
dynamic force analysis solves the wrench balance in the least-squares sense and reports the
unbalanced residual (docs/models/4ups_1rps.md).

Assumptions where the paper is silent (all are parameters):

* ``base_offset``: the universal-joint centres' Y coordinate, i.e. their distance from the
  fixed-platform plane Y = 0 along Y (the paper gives no height for them). Default -0.125 m
  (the centres 125 mm below that plane, on the side away from the moving platform),
  calibrated on the grinding-point workspace of Section 3.3: it puts the lower end of the
  workspace at the paper's -0.11..0.11 m while the top stays where d2_max puts it
  (d2_max - l_s0 + y_T = 0.575 m, the paper's 0.57 m). Legs as long as Table 2's l_max reach
  that top only for base_offset >= -0.135 m. With base_offset = 0 the workspace spans only
  Y 0.43..0.575 m. See docs/reproduction.md.
* ``u_angles`` follow Table 2: U1..U4 on a circle of radius ``base_radius`` (0.335 m) in the
  XZ plane, angle measured from +X towards +Z, with 53 deg between U1 and U2 and 127 deg
  between U2 and U3; the U1-U2 side is centred on ``u_phase`` (default 0, i.e. on +X, so the
  long side of the rectangle runs along X). ``u_phase = 90 deg`` (long side along Z) gives a
  wider workspace (X about +-0.36 m) whose lower end is as wide as the rest. That is not the
  narrowing sector of the paper's Figures 7 and 23, hence the default 0.
* ``platform_angles``: spheres at -45, 45, 135, 225 deg on the circle of radius
  ``platform_radius`` (0.1 m) in the platform's xz plane ("evenly distributed", Section 3.2),
  each paired with the nearest universal joint. A common offset of the four angles is a spin
  of the platform about its normal. That spin moves neither the platform centre nor the
  grinding point, so it does not change the grinding-point workspace.
* Universal-joint fixed axes tangential to the base circle.
* Gravity along -Y (parameter of the force analyses, not of the kinematics).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..constraints import (ActuatorRange, Constraint, JointAngleLimit, LegAxisAngle, LegInterference,
                           LegLengthRange)
from ..legs import RPS, UPS
from ..mechanism import Mechanism, check_angles, check_finite, check_length
from ..spatial import euler_rate_map, euler_to_matrix

__all__ = ["UPSRPSGrindingParams", "UPSRPSGrinding"]


@dataclass(frozen=True)
class UPSRPSGrindingParams:
    """Parameters in SI (m, rad). Defaults: the 2022 paper's Table 2 where it gives them."""

    UNITS: ClassVar[dict] = {**{k: "length" for k in ("platform_radius", "base_radius", "l_s0", "y_t",
                                                      "base_offset", "l_min", "l_max", "d2_min", "d2_max",
                                                      "leg_diameter")},
                             **{k: "angle" for k in ("mu1", "mu2", "u_phase", "platform_angles", "theta1_max",
                                                     "sphere_max", "ujoint_max")}}


    platform_radius: float = 0.10
    base_radius: float = 0.335
    mu1: float = float(np.deg2rad(53.0))
    mu2: float = float(np.deg2rad(127.0))
    l_s0: float = 0.05
    y_t: float = 0.075
    base_offset: float = -0.125
    u_phase: float = 0.0
    platform_angles: tuple = tuple(np.deg2rad([-45.0, 45.0, 135.0, 225.0]).tolist())
    # Limits of Table 2 (used by constraint margins).
    l_min: float = 0.43
    l_max: float = 0.68
    d2_min: float = 0.32
    d2_max: float = 0.55
    theta1_max: float = float(np.pi / 3)
    sphere_max: float = float(np.pi / 4)
    ujoint_max: float = float(np.pi / 4)
    leg_diameter: float = 0.035

    def __post_init__(self):
        for k in ("platform_radius", "base_radius", "l_min", "l_max", "d2_min", "d2_max", "leg_diameter"):
            object.__setattr__(self, k, check_length(f"4ups_1rps.{k}", getattr(self, k)))
        object.__setattr__(self, "l_s0", check_length("4ups_1rps.l_s0", self.l_s0, allow_zero=True))
        object.__setattr__(self, "y_t", check_finite("4ups_1rps.y_t", self.y_t))
        object.__setattr__(self, "base_offset", check_finite("4ups_1rps.base_offset", self.base_offset))
        object.__setattr__(self, "u_phase", check_finite("4ups_1rps.u_phase", self.u_phase))
        for k in ("mu1", "mu2", "theta1_max", "sphere_max", "ujoint_max"):
            v = check_finite(f"4ups_1rps.{k}", getattr(self, k))
            if not 0 < v < np.pi:
                raise ValueError(f"4ups_1rps.{k} must be an angle in (0, pi) rad, got {v}")
            object.__setattr__(self, k, v)
        if not self.l_min < self.l_max:
            raise ValueError(f"4ups_1rps.l_min must be < l_max, got {self.l_min} >= {self.l_max}")
        if not self.d2_min < self.d2_max:
            raise ValueError(f"4ups_1rps.d2_min must be < d2_max, got {self.d2_min} >= {self.d2_max}")
        object.__setattr__(self, "platform_angles", check_angles("4ups_1rps.platform_angles", self.platform_angles, 4))

    @property
    def u_angles(self) -> np.ndarray:
        a1 = self.u_phase - self.mu1 / 2
        return np.array([a1, a1 + self.mu1, a1 + self.mu1 + self.mu2, a1 + 2 * self.mu1 + self.mu2])


@dataclass(frozen=True)
class _CentreAxisAngle(Constraint):
    """phi_o of eq. (9): angle between the platform's y axis and the position vector of the
    platform centre from the fixed-platform centre, at most ``hi``."""

    hi: float = np.pi / 4
    unit: str = "rad"

    def margin(self, ctx):
        n_o = ctx.p / np.linalg.norm(ctx.p, axis=-1, keepdims=True)
        yp = ctx.R[:, :, 1]
        return self.hi - np.arccos(np.clip(np.sum(n_o * yp, -1), -1.0, 1.0))


class UPSRPSGrinding(Mechanism):
    name = "4ups_1rps"
    paper = "Wang, Liang, Zhou, Yang, Wang (2022), Analysis of position, pose and force decoupling characteristics of a 4-UPS/1-RPS parallel grinding robot"
    Params = UPSRPSGrindingParams
    task_coordinates = ("x", "y", "alpha", "beta", "gamma")
    angular_coordinates = frozenset({"alpha", "beta", "gamma"})

    def __init__(self, params: UPSRPSGrindingParams | None = None):
        P = params or UPSRPSGrindingParams()
        self.params = P
        legs = []
        for i, (ua, pa) in enumerate(zip(P.u_angles, P.platform_angles)):
            base = np.array([P.base_radius * np.cos(ua), P.base_offset, P.base_radius * np.sin(ua)])
            plat = P.platform_radius * np.array([np.cos(pa), 0.0, np.sin(pa)])
            legs.append(UPS(f"L{i + 1}", base=base, platform=plat, u_axis=[-np.sin(ua), 0.0, np.cos(ua)]))
        legs.append(RPS("L5", base=[0.0, -P.l_s0, 0.0], platform=[0.0, 0.0, 0.0], r_axis=[0, 0, 1], passive=True))
        super().__init__(P, legs, home=[0.0, 0.42, 0.0, 0.0, 0.0], length_scale=P.base_radius)

    def default_ranges(self) -> dict:
        """Platform-centre box with moderate tilts, SI (the paper's Figure 5 region)."""
        return {"x": (-0.5, 0.5), "y": (0.0, 0.6), "alpha": (-np.pi, np.pi), "beta": (0.0, np.pi / 4),
                "gamma": (-np.pi, np.pi)}

    def _pose(self, X):
        p = np.stack([X[:, 0], X[:, 1], np.zeros(X.shape[0])], -1)
        return p, euler_to_matrix("zyz", X[:, 2:5])

    def _twist_map(self, X):
        N = X.shape[0]
        T = np.zeros((N, 6, 5))
        T[:, 0, 0] = T[:, 1, 1] = 1.0
        T[:, 3:, 2:] = euler_rate_map("zyz", X[:, 2:5])
        return T

    def build_constraints(self):
        """The rows of eq. (9) with Table 2's limits, in order: driving-leg stroke, constraining
        stroke d2, revolute angle theta1, sphere angles phi_i^m (leg against the platform's y
        axis), the constraining sphere angle phi_o (platform y axis against the position vector
        n_o of the platform centre), universal-joint angles phi_i^s (leg against the base Y
        axis), and D <= D_i for adjacent driving legs."""
        P = self.params
        drive = ("L1", "L2", "L3", "L4")
        y = (0.0, 1.0, 0.0)
        return [
            ActuatorRange("stroke", lo=P.l_min, hi=P.l_max, doc="l_min <= l_i <= l_max"),
            LegLengthRange("d2", legs=("L5",), lo=P.d2_min, hi=P.d2_max, doc="d2_min <= d2 <= d2_max"),
            JointAngleLimit("theta1", key="R_base", legs=("L5",), lo=-P.theta1_max, hi=P.theta1_max,
                            doc="theta1_min <= theta1 <= theta1_max"),
            LegAxisAngle("sphere_platform", legs=drive, axis=y, frame="platform", hi=P.sphere_max,
                         doc="phi_i^m = arccos(L_i . R n_mi / l_i) <= phi_1max"),
            _CentreAxisAngle("sphere_constraint", hi=P.sphere_max,
                             doc="phi_o = arccos(R n_mi . n_o / |n_o|) <= phi_1max"),
            LegAxisAngle("ujoint_base", legs=drive, axis=y, frame="base", hi=P.ujoint_max,
                         doc="phi_i^s = arccos(L_i . n_si / l_i) <= phi_2max"),
            LegInterference("interference", diameter=P.leg_diameter,
                            pairs=(("L1", "L2"), ("L2", "L3"), ("L3", "L4"), ("L4", "L1")),
                            doc="D <= D_i, adjacent driving legs"),
        ]

    def grinding_point(self, X) -> np.ndarray:
        """Grinding point (N, 3) in the base frame, eq. (10): platform point (0, y_T, 0)."""
        Xa, single = self._poses(X)
        p, R = self.pose(Xa)
        g = p + R @ np.array([0.0, self.params.y_t, 0.0])
        return g[0] if single else g
