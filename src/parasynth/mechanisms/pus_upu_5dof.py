"""5-PUS/UPU 3T2R mechanism (Wang, Lyu & Liu, Appl. Sci. 2021): model ``"5pus_upu"``.

Structure (paper Sections 2 and 3): five driving limbs P-U-S with vertical ball-screw sliders
whose universal-joint centres U_i lie on a circle of radius ``slider_radius`` (R = 135 mm), a
fixed-length link U_i S_i (L = 205 mm) and a sphere S_i on the moving platform; one passive
U-P-U constraining limb from the centre of the base to the centre of the platform.

Frames: base frame O_p-XYZ with Z along the slider screws; the slider coordinate is the Z of
the universal-joint centre, ``s_i = Z_i^U`` (eq. (11) with its positive sign: the sliders are
above the platform). Platform frame o_b-xyz at the platform centre.

Orientation. Eq. (7) writes the platform orientation as ``Ry(beta) Rx(alpha)`` with gamma = 0
and treats x, y, z, alpha, beta as independent. A real U-P-U constraining limb cannot hold
that family at every position: with its base axis along Y, its two middle axes parallel and
its platform axis along the platform's y (the paper's Figure 3), the platform orientation is
``Ry(q1) Rx(alpha) Ry(q4)`` where ``q1 = atan2(x - x_B, z - z_B)`` is fixed by the limb's
direction. The model therefore uses ``R = Ry(q1) Rx(alpha) Ry(beta - q1)``: alpha is the
rotation about the limb's cross axis and beta the total rotation about y. This equals eq. (7)
exactly whenever alpha = 0 (R = Ry(beta): the paper's fixed-posture workspaces and its test
trajectory) or beta = q1, and keeps the kinematic model consistent with the limb's constraint
(its constraint wrench does no work on any motion of the model). Elsewhere the two differ by a
rotation of second order, about alpha * (beta - q1).

Schemes (parameter ``platform``):

* ``"rectangular"`` (default, the improved scheme, Section 2.4): sphere centres given by
  ``hinge_layout``:

  - ``"scheme1"`` (default): the prototype's coordinates (35, 51), (-35, 51), (-51, -35),
    (51, -35), (0, 51) mm (Sections 3.2 and 5; Figure 14a);
  - ``"scheme2"``: Figure 14b, whose coordinates the text does not give. Assumed: the sphere
    centres on the corners of the 80 mm square platform (40, 40), (-40, 40), (-40, -40),
    (40, -40) mm and (0, 40) mm, each paired with the same slider as in scheme 1;
  - ``"custom"``: ``hinge_points``.

  The layout is then scaled by ``hinge_scale`` about the platform centre, rotated by
  ``hinge_rotation`` about the platform normal and shifted by ``hinge_shift_y`` along y:
  three continuous parameters for optimising the layout.
* ``"pentagonal"``: the first scheme (Section 2.1), a regular pentagon of radius
  ``pentagon_radius`` similar to and aligned with the slider pentagon. With the platform
  parallel to the base and centred above the origin, the five link lines meet in one point and
  the wrench system loses rank (the paper's "structural singularity", Section 2.3).

Assumptions where the paper is silent (all are parameters):

* ``slider_angles``: the angular positions of the sliders. The paper says only "regular
  pentagon"; we put slider 5 on +Y (sphere 5 is at (0, 51) mm) and pair each slider with the
  nearest sphere: 18, 162, 234, 306, 90 deg for sliders 1..5.
* ``pentagon_radius`` (62 mm) for the first scheme: not given; any value shows the singularity.
* ``upu_base_z`` (-0.15 m): height of the constraining limb's base universal joint. Only the
  passive limb's length and its constraint wrench direction depend on it (at the reference
  pose its constraint is the pure couple about Z of eq. (6) whatever the height). It must lie
  below the workspace (z >= -0.097 m with the default stroke), where the limb would have zero
  length; the +-5 deg workspace changes by less than 2 mm for any height from -0.10 to -0.40 m.
* ``slider_min``, ``slider_max`` (0.085, 0.290 m): the 205 mm stroke of Section 5, placed
  around the reference pose. At a fixed orientation the placement only shifts the workspace
  along Z; the paper gives no absolute heights.
* ``sphere_max`` (25 deg) and ``ujoint_max`` (40 deg): joint cone-angle limits, not stated in
  the paper. At alpha = beta = 0 both cone angles equal the angle between a link and its
  reference direction, so only the smaller limit acts. 25 deg balances the XOY sizes of the
  paper's fixed-posture workspaces (120 x 175 mm at alpha = beta = 0, 80 x 150 mm within
  +-5 deg): the model gives 137 x 145 mm and 113 x 119 mm, 3 % and 6 % off in the geometric
  mean. The model's workspace is nearly isotropic in X and Y, so no limit reproduces the
  paper's aspect ratio (docs/reproduction.md). The spherical joint is the limiting one, as
  the paper says (Sections 2.4.2 and 4.1); 40 deg is a common universal-joint range.
* The constraining limb's universal-joint axes: base axis Y, middle axes parallel, platform
  axis y (platform frame), as in the paper's Figure 3 (its screw system (6)); see Orientation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..constraints import ActuatorRange, JointAngleLimit, LegInterference
from ..legs import PUS, UPU
from ..mechanism import Mechanism, check_angles, check_finite, check_length, check_points
from ..spatial import euler_rate_map, euler_to_matrix

__all__ = ["PUSUPU5Params", "PUSUPU5", "trajectory_eq13"]

_MM = 1e-3

#: Sphere-centre layouts of the rectangular platform (platform frame, m), sliders 1..5.
HINGE_LAYOUTS = {
    "scheme1": ((35 * _MM, 51 * _MM), (-35 * _MM, 51 * _MM), (-51 * _MM, -35 * _MM), (51 * _MM, -35 * _MM),
                (0.0, 51 * _MM)),
    "scheme2": ((40 * _MM, 40 * _MM), (-40 * _MM, 40 * _MM), (-40 * _MM, -40 * _MM), (40 * _MM, -40 * _MM),
                (0.0, 40 * _MM)),
    "custom": None,
}


@dataclass(frozen=True)
class PUSUPU5Params:
    """Parameters in SI (m, rad). Defaults: the 2021 paper's prototype (Sections 3.2 and 5)."""

    UNITS: ClassVar[dict] = {"slider_radius": "length", "link_length": "length", "platform": None,
                             "hinge_points": "length", "hinge_layout": None,
                             "hinge_scale": "dimensionless", "hinge_rotation": "angle", "hinge_shift_y": "length",
                             "pentagon_radius": "length", "slider_angles": "angle",
                             "upu_base_z": "length", "slider_min": "length", "slider_max": "length",
                             "sphere_max": "angle", "ujoint_max": "angle", "link_diameter": "length"}


    slider_radius: float = 0.135
    link_length: float = 0.205
    platform: str = "rectangular"
    hinge_points: tuple = ((35 * _MM, 51 * _MM), (-35 * _MM, 51 * _MM), (-51 * _MM, -35 * _MM),
                           (51 * _MM, -35 * _MM), (0.0, 51 * _MM))
    hinge_layout: str = "scheme1"
    hinge_scale: float = 1.0
    hinge_rotation: float = 0.0
    hinge_shift_y: float = 0.0
    pentagon_radius: float = 0.062
    slider_angles: tuple = tuple(np.deg2rad([18.0, 162.0, 234.0, 306.0, 90.0]).tolist())
    upu_base_z: float = -0.15
    # Limits. Stroke 205 mm (Section 5), placed around the reference pose; joint limits are not
    # stated in the paper (sphere_max calibrated on the Section 4.3 workspace sizes, see the
    # module docstring); link diameter 8 mm (Section 5).
    slider_min: float = 0.085
    slider_max: float = 0.290
    sphere_max: float = float(np.deg2rad(25.0))
    ujoint_max: float = float(np.deg2rad(40.0))
    link_diameter: float = 0.008

    def __post_init__(self):
        for k in ("sphere_max", "ujoint_max", "link_diameter"):
            object.__setattr__(self, k, check_length(f"5pus_upu.{k}", getattr(self, k)))
        for k in ("slider_min", "slider_max"):
            object.__setattr__(self, k, check_finite(f"5pus_upu.{k}", getattr(self, k)))
        if not self.slider_min < self.slider_max:
            raise ValueError(f"5pus_upu.slider_min must be < slider_max, got {self.slider_min} >= {self.slider_max}")
        object.__setattr__(self, "slider_radius", check_length("5pus_upu.slider_radius", self.slider_radius))
        object.__setattr__(self, "link_length", check_length("5pus_upu.link_length", self.link_length))
        object.__setattr__(self, "pentagon_radius", check_length("5pus_upu.pentagon_radius", self.pentagon_radius))
        object.__setattr__(self, "upu_base_z", check_finite("5pus_upu.upu_base_z", self.upu_base_z))
        if self.platform not in ("rectangular", "pentagonal"):
            raise ValueError(
                f"5pus_upu.platform must be 'rectangular' (improved scheme) or 'pentagonal' "
                f"(first scheme), got {self.platform!r}"
            )
        object.__setattr__(self, "hinge_points", check_points("5pus_upu.hinge_points", self.hinge_points, 5, 2))
        if self.hinge_layout not in HINGE_LAYOUTS:
            raise ValueError(f"5pus_upu.hinge_layout must be one of {sorted(HINGE_LAYOUTS)}, got {self.hinge_layout!r}")
        object.__setattr__(self, "hinge_scale", check_length("5pus_upu.hinge_scale", self.hinge_scale))
        object.__setattr__(self, "hinge_rotation", check_finite("5pus_upu.hinge_rotation", self.hinge_rotation))
        object.__setattr__(self, "hinge_shift_y", check_finite("5pus_upu.hinge_shift_y", self.hinge_shift_y))
        object.__setattr__(self, "slider_angles", check_angles("5pus_upu.slider_angles", self.slider_angles, 5))

    def sphere_centres(self) -> np.ndarray:
        """Sphere centres (5, 3) in the platform frame (m) for the rectangular platform."""
        base = np.asarray(self.hinge_points if self.hinge_layout == "custom" else HINGE_LAYOUTS[self.hinge_layout])
        c, s = np.cos(self.hinge_rotation), np.sin(self.hinge_rotation)
        xy = self.hinge_scale * base @ np.array([[c, s], [-s, c]])
        xy[:, 1] += self.hinge_shift_y
        return np.column_stack([xy, np.zeros(5)])


class PUSUPU5(Mechanism):
    name = "5pus_upu"
    paper = "Wang, Lyu, Liu (2021), Kinematic analysis and verification of a new 5-DOF parallel mechanism"
    Params = PUSUPU5Params
    task_coordinates = ("x", "y", "z", "alpha", "beta")
    angular_coordinates = frozenset({"alpha", "beta"})

    def __init__(self, params: PUSUPU5Params | None = None):
        P = params or PUSUPU5Params()
        self.params = P
        ang = np.asarray(P.slider_angles)
        if P.platform == "rectangular":
            sph = list(P.sphere_centres())
        else:
            sph = [P.pentagon_radius * np.array([np.cos(a), np.sin(a), 0.0]) for a in ang]
        legs = []
        for i, a in enumerate(ang):
            base = P.slider_radius * np.array([np.cos(a), np.sin(a), 0.0])
            tangent = np.array([-np.sin(a), np.cos(a), 0.0])
            legs.append(PUS(f"L{i + 1}", base=base, platform=sph[i], slider_axis=[0, 0, 1],
                            link_length=P.link_length, branch=1, u_axis=tangent))
        legs.append(UPU("L6", base=[0.0, 0.0, P.upu_base_z], platform=[0.0, 0.0, 0.0],
                        u_axis=[0.0, 1.0, 0.0], u_platform_axis=[0.0, 1.0, 0.0], passive=True))
        super().__init__(P, legs, home=[0.0, 0.0, 0.0, 0.0, 0.0], length_scale=P.slider_radius)

    def build_constraints(self):
        """Section 4.1's factors: slider stroke, spherical and universal joint angles (cone
        angle from the joint's neutral direction, the link direction at the reference pose)
        and link interference (centre-line distance >= link diameter, driving links)."""
        P = self.params
        pus = tuple(f"L{i}" for i in range(1, 6))
        return [
            ActuatorRange("stroke", lo=P.slider_min, hi=P.slider_max, doc="slider_min <= s_i <= slider_max"),
            JointAngleLimit("sphere_limit", key="S_platform_cone", hi=P.sphere_max, legs=pus,
                            doc="spherical joint cone angle <= sphere_max"),
            JointAngleLimit("ujoint_limit", key="U_base_cone", hi=P.ujoint_max, legs=pus,
                            doc="universal joint cone angle <= ujoint_max"),
            LegInterference("interference", diameter=P.link_diameter, legs=pus,
                            doc="distance between link centre lines >= link_diameter"),
        ]

    def default_ranges(self) -> dict:
        """Fixed-posture box (alpha = beta = 0) around the paper's workspace (Section 4.3), SI."""
        return {"x": (-0.15, 0.15), "y": (-0.15, 0.15), "z": (-0.30, 0.20)}

    def _q1(self, X):
        """Rotation of the constraining limb's base universal joint about Y, and the partial
        derivatives of it with respect to x and z."""
        dx = X[:, 0]
        dz = X[:, 2] - self.params.upu_base_z
        r2 = dx * dx + dz * dz
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.arctan2(dx, dz), dz / r2, -dx / r2

    def pose_valid(self, X):
        ok = np.all(np.isfinite(X), axis=-1)
        dx = np.where(ok, X[:, 0], 1.0)
        dz = np.where(ok, X[:, 2], 1.0) - self.params.upu_base_z
        return ok & (dx * dx + dz * dz > 1e-12)

    def _pose(self, X):
        p = X[:, :3].copy()
        q1, _, _ = self._q1(X)
        alpha, beta = X[:, 3], X[:, 4]
        R = euler_to_matrix("yxy", np.stack([q1, alpha, beta - q1], -1))
        return p, R

    def _twist_map(self, X):
        N = X.shape[0]
        q1, dq1_dx, dq1_dz = self._q1(X)
        alpha = X[:, 3]
        E = euler_rate_map("yxy", np.stack([q1, alpha, X[:, 4] - q1], -1))  # columns: q1, alpha, (beta - q1)
        T = np.zeros((N, 6, 5))
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = 1.0
        w_q1 = E[:, :, 0] - E[:, :, 2]
        T[:, 3:, 0] = w_q1 * dq1_dx[:, None]
        T[:, 3:, 2] = w_q1 * dq1_dz[:, None]
        T[:, 3:, 3] = E[:, :, 1]
        T[:, 3:, 4] = E[:, :, 2]
        return T


def trajectory_eq13(t, attitude_follows_curve: bool = False):
    """The 2021 paper's test trajectory, eq. (13), as task coordinates and their first and
    second time derivatives (each (N, 5), SI).

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
