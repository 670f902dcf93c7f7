"""A manufacturing task as the input of a design: required poses, path, loads, space, floors.

A :class:`Task` says what the robot must do, independently of any design: the poses its tool
must reach (a grid, lists, a CSV file, in an order), the path through them (a jerk-limited
point-to-point profile, :mod:`parasynth.model.trajectory`, or timed samples), the payload and
the process wrench, the installation space every body must stay in, and floors that must
hold at every pose and path sample. The measures of a design on a task are in
:mod:`parasynth.measures.task`; docs/tasks.md describes the format.

Frames (SI units throughout)
----------------------------
* ``B``: the mechanism's base frame (its description's frame).
* ``W``: the task frame, where the task is written. Its pose in ``B`` is the **placement**:
  an offset ``(x, y, z)`` and a yaw about ``B``'s z axis, optionally hanging (``W`` turned
  180 deg about its x axis: a robot hanging from above, whose base z axis points down in the
  workcell). ``R_BW = Rz(yaw) Rx(pi if hanging)``, ``p_BW = (x, y, z)``.
* ``P``: the platform frame (the mechanism's platform reference point and orientation).
* ``T``: the tool frame, fixed to the platform: an offset ``(x, y, z)`` along the platform's
  axes and a yaw about the platform's z axis, ``R_PT = Rz(tool_yaw)``.

Required poses
--------------
A pose is a set of named coordinates; a coordinate not named takes its home value.

* For a mechanism with 6 task coordinates the names are ``x, y, z`` (position of the frame's
  origin in ``W``) and ``alpha, beta, gamma``, the angles of the task's Euler convention
  (default ``xyz``: X-Y'-Z'' intrinsic, ``R = Rx(alpha) Ry(beta) Rz(gamma)``, as
  :func:`parasynth.model.spatial.euler_to_matrix`); home is the tool's pose in ``W`` at the
  mechanism's home pose.
* For a mechanism with fewer freedoms the poses are given in its own task coordinates (its
  ``task_coordinates``, e.g. ``z, psi, theta``); a name it does not have is an error
  (:class:`TaskError`) when the task meets the mechanism. They describe the **platform**
  (its own parametrisation read in ``W``: without a placement the mechanism's coordinates are
  the given ones); a tool only places the tool point (where the wrench acts, the stiffness
  and the position error are taken), since such a mechanism cannot in general hold a tool
  pose derived from its own coordinates (its freedoms are coupled).

Poses describe the tool frame (``frame="tool"``, the default of a task file) or the platform
frame (``frame="platform"``; the default of ``Task(poses=X)`` with an unnamed array, whose
columns are the mechanism's own task coordinates in its order). The platform pose in ``B`` is
``R_BP = R_BW R_WT R_PT^T``, ``p_BP = p_BW + R_BW (p_WT - R_WP p_PT)``; the mechanism's task
coordinates follow by a damped Gauss-Newton solve of its pose parametrisation (exact in one
step where the parametrisation is the task's own), and a platform pose outside the
mechanism's freedoms (a residual above 1e-9 of the length scale) is an error naming the pose.

Loads
-----
``wrench`` ``[fx, fy, fz, mx, my, mz]`` (N, N m) acts at the tool point, in ``W``
(``wrench_frame="task"``, the default; ``W = B`` without a placement), ``B`` (``"base"``) or the
tool frame (``"tool"``, turning with it); one wrench or one per pose; ``wrench_signs=True``
takes, per actuator, the worst of every sign combination of its nonzero components. The
``payload`` (mass, centre of mass in the platform frame, inertia about the centre of mass in
the platform frame) weighs ``gravity`` (default 9.80665 m/s^2) along ``-z`` of ``W``, or along a
gravity vector given in ``W`` (for a model whose vertical is another axis, e.g. ``4ups_1rps``'s y).
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .spatial import EULER_CONVENTIONS, euler_rate_map, euler_to_matrix, rot_x, rot_z
from .trajectory import LIMIT_MODES, TIMINGS, MotionLimits, PathSamples, sample_path
from ..common.units import UNIT_KINDS, QuantityError, _ureg, format_quantity, parse_quantity

__all__ = ["Task", "TaskError", "Payload", "Placement", "Tool", "Space", "TrajectorySpec", "STANDARD_NAMES", "G0",
           "matrix_to_euler", "rotation_log", "FLOOR_KINDS"]

#: Standard gravity (m/s^2).
G0 = 9.80665
#: Pose coordinates of a task for a mechanism with six task coordinates.
STANDARD_NAMES = ("x", "y", "z", "alpha", "beta", "gamma")
_ANGLES = ("alpha", "beta", "gamma")
#: Euler conventions a task may name (three angles each).
TASK_CONVENTIONS = tuple(k for k, v in EULER_CONVENTIONS.items() if len(v) == 3)
#: Floors a task may state: {name: (bound, what)}.
FLOOR_KINDS = {"singularity_margin": ("min", "singularity margin"), "condition": ("max", "condition number (SI)"),
               "lti": ("min", "local transmission index")}


class TaskError(ValueError):
    """A task that cannot be read or does not fit a mechanism; the message starts with the key
    path (``task.poses.grid.x: ...``)."""


# ---------------------------------------------------------------------------------------------
# rotations
# ---------------------------------------------------------------------------------------------
_AX = {"x": 0, "y": 1, "z": 2}


def matrix_to_euler(convention: str, R) -> np.ndarray:
    """Angles (..., 3) of rotation matrices ``R`` (..., 3, 3) in a three-angle convention of
    :data:`parasynth.model.spatial.EULER_CONVENTIONS` (``R = R_a1(q1) R_a2(q2) R_a3(q3)``); the
    inverse of :func:`~parasynth.model.spatial.euler_to_matrix` on the principal branch
    (middle angle in [-pi/2, pi/2] for Tait-Bryan, [0, pi] for proper Euler sequences)."""
    seq = EULER_CONVENTIONS.get(convention)
    if seq is None or len(seq) != 3:
        raise ValueError(f"unknown Euler convention {convention!r}; allowed: {', '.join(TASK_CONVENTIONS)}")
    R = np.asarray(R, dtype=float)
    i, j = _AX[seq[0]], _AX[seq[1]]
    if seq[0] != seq[2]:  # Tait-Bryan
        k = _AX[seq[2]]
        eps = 1.0 if (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
        b = np.arcsin(np.clip(eps * R[..., i, k], -1.0, 1.0))
        a = np.arctan2(-eps * R[..., j, k], R[..., k, k])
        c = np.arctan2(-eps * R[..., i, j], R[..., i, i])
    else:  # proper Euler i-j-i, k the third axis
        k = 3 - i - j
        eps = 1.0 if (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
        b = np.arccos(np.clip(R[..., i, i], -1.0, 1.0))
        a = np.arctan2(R[..., j, i], -eps * R[..., k, i])
        c = np.arctan2(R[..., i, j], eps * R[..., i, k])
    return np.stack([a, b, c], axis=-1)


def rotation_log(R) -> np.ndarray:
    """Rotation vectors (..., 3) (axis times angle in [0, pi]) of rotation matrices ``R``."""
    R = np.asarray(R, dtype=float)
    w = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    c = np.clip(0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    s = np.linalg.norm(w, axis=-1)
    ang = np.arctan2(s, c)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(s > 1e-12, ang / np.where(s > 1e-12, s, 1.0), 1.0)
    out = w * f[..., None]
    # near pi the skew part vanishes: the axis from the symmetric part
    near = (c < -0.99) & (s < 1e-6)
    if np.any(near):
        B = 0.5 * (R[near] + np.eye(3))
        k = np.argmax(np.einsum("nii->ni", B), axis=-1)
        ax = B[np.arange(len(k)), :, k]
        ax = ax / np.linalg.norm(ax, axis=-1, keepdims=True)
        out[near] = ax * ang[near][:, None]
    return out


def rotation_exp(v) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors ``v`` (..., 3) (Rodrigues)."""
    v = np.asarray(v, dtype=float)
    th = np.linalg.norm(v, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        k = np.where(th[..., None] > 0, v / np.where(th > 0, th, 1.0)[..., None], 0.0)
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = k[..., 2], -k[..., 1], k[..., 0]
    s, c = np.sin(th)[..., None, None], np.cos(th)[..., None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


# ---------------------------------------------------------------------------------------------
# parts of a task
# ---------------------------------------------------------------------------------------------
def _vec(where, v, n, what="m"):
    try:
        a = np.asarray(v, dtype=float) if not isinstance(v, (str, bytes, Mapping)) else None
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != (n,) or not np.all(np.isfinite(a)):
        raise TaskError(f"{where}: give {n} finite numbers ({what}), got {v!r}")
    return tuple(float(x) for x in a)


def _num(where, v, what="a number", low=None, strict=False):
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
        raise TaskError(f"{where}: give {what}, got {v!r}")
    v = float(v)
    if low is not None and (v <= low if strict else v < low):
        raise TaskError(f"{where}: must be {'>' if strict else '>='} {low}, got {v!r}")
    return v


@dataclass(frozen=True)
class Placement:
    """Pose of the task frame ``W`` in the base frame ``B``: ``offset`` (m), ``yaw`` (rad) about
    ``B``'s z axis, ``hanging`` (``W`` turned 180 deg about x: a robot hanging from above)."""

    offset: tuple = (0.0, 0.0, 0.0)
    yaw: float = 0.0
    hanging: bool = False

    def __post_init__(self):
        object.__setattr__(self, "offset", _vec("placement.offset", self.offset, 3))
        object.__setattr__(self, "yaw", _num("placement.yaw", self.yaw, "an angle (rad)"))
        if not isinstance(self.hanging, bool):
            raise TaskError(f"placement.hanging: give true or false, got {self.hanging!r}")

    @cached_property
    def R(self) -> np.ndarray:
        """``R_BW`` (read-only, computed once)."""
        R = rot_z(self.yaw) @ (rot_x(np.pi) if self.hanging else np.eye(3))
        R.setflags(write=False)
        return R

    @property
    def p(self) -> np.ndarray:
        return np.array(self.offset)

    @property
    def identity(self) -> bool:
        return not any(self.offset) and self.yaw == 0.0 and not self.hanging


@dataclass(frozen=True)
class Tool:
    """The tool frame on the platform: ``offset`` (m, along the platform's axes) and ``yaw``
    (rad, about the platform's z axis)."""

    offset: tuple = (0.0, 0.0, 0.0)
    yaw: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "offset", _vec("tool", self.offset, 3))
        object.__setattr__(self, "yaw", _num("tool.yaw", self.yaw, "an angle (rad)"))

    @cached_property
    def R(self) -> np.ndarray:
        """``R_PT`` (read-only, computed once)."""
        R = rot_z(self.yaw)
        R.setflags(write=False)
        return R

    @property
    def identity(self) -> bool:
        return not any(self.offset) and self.yaw == 0.0


@dataclass(frozen=True)
class Payload:
    """What the platform carries: ``mass`` (kg), ``com`` (m, platform frame), ``inertia`` about
    the centre of mass in the platform frame (kg m^2: three principal moments along the
    platform axes, or a symmetric 3x3 tensor)."""

    mass: float = 0.0
    com: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    def __post_init__(self):
        object.__setattr__(self, "mass", _num("payload.mass", self.mass, "a mass >= 0 (kg)", low=0.0))
        object.__setattr__(self, "com", _vec("payload.com", self.com, 3))
        try:
            I = np.asarray(self.inertia, dtype=float) if not isinstance(self.inertia, (str, Mapping)) else None
        except (TypeError, ValueError):
            I = None
        if I is not None and I.shape == (3,):
            I = np.diag(I)
        if I is None or I.shape != (3, 3) or not np.all(np.isfinite(I)) or not np.allclose(I, I.T) \
                or np.any(np.linalg.eigvalsh(I) < -1e-12 * max(1.0, float(np.abs(I).max()))):
            raise TaskError(f"payload.inertia: give 3 principal moments or a symmetric positive semi-definite "
                            f"3x3 tensor (kg m^2), got {self.inertia!r}")
        object.__setattr__(self, "inertia", tuple(map(tuple, I.tolist())))

    @property
    def tensor(self) -> np.ndarray:
        return np.array(self.inertia)


@dataclass(frozen=True)
class Space:
    """Installation space in ``W``: a ``box`` (``low``, ``high`` corners, m) or a ``cylinder``
    (``radius``, ``center`` (x, y), ``z`` = (low, high), m) that every body must stay inside;
    ``base_plane``: whether moving parts (platform points and the platform ends of the legs)
    may pass to the other side of the base plane (z = 0 of ``B``) from where the platform is
    at home."""

    shape: str = "box"
    low: tuple = (-1.0, -1.0, -1.0)
    high: tuple = (1.0, 1.0, 1.0)
    radius: float = 1.0
    center: tuple = (0.0, 0.0)
    z: tuple = (-1.0, 1.0)
    base_plane: bool = True

    def __post_init__(self):
        if self.shape not in ("box", "cylinder"):
            raise TaskError(f"space: shape must be box or cylinder, got {self.shape!r}")
        if self.shape == "box":
            lo, hi = _vec("space.box.low", self.low, 3), _vec("space.box.high", self.high, 3)
            if not all(a < b for a, b in zip(lo, hi)):
                raise TaskError(f"space.box: low must be below high on every axis, got low {lo}, high {hi}")
            object.__setattr__(self, "low", lo)
            object.__setattr__(self, "high", hi)
        else:
            object.__setattr__(self, "radius", _num("space.cylinder.radius", self.radius, "a radius > 0 (m)",
                                                    low=0.0, strict=True))
            object.__setattr__(self, "center", _vec("space.cylinder.center", self.center, 2))
            z = _vec("space.cylinder.z", self.z, 2)
            if not z[0] < z[1]:
                raise TaskError(f"space.cylinder.z: low must be below high, got {z}")
            object.__setattr__(self, "z", z)
        if not isinstance(self.base_plane, bool):
            raise TaskError(f"space.base_plane: give true or false, got {self.base_plane!r}")

    def clearance(self, pts) -> np.ndarray:
        """Signed distance (..., ) of points (..., 3) in ``W`` to the boundary: positive inside
        (the distance to the nearest face), negative outside (minus the distance to the space)."""
        x = np.asarray(pts, dtype=float)
        if self.shape == "box":
            lo, hi = np.array(self.low), np.array(self.high)
            # e > 0 on an axis where the point is outside; inside, -max(e) is the nearest face's distance
            e = np.maximum(lo - x, x - hi)
            emax = e.max(axis=-1)
            d = -emax
            out = emax > 0
            if out.any():
                d[out] = -np.linalg.norm(np.maximum(e[out], 0.0), axis=-1)
            return d
        c = np.array(self.center)
        r = np.linalg.norm(x[..., :2] - c, axis=-1)
        zl, zh = self.z
        d_in = np.minimum(self.radius - r, np.minimum(x[..., 2] - zl, zh - x[..., 2]))
        dr = np.maximum(r - self.radius, 0.0)
        dz = np.maximum(np.maximum(zl - x[..., 2], x[..., 2] - zh), 0.0)
        return np.where(d_in >= 0, d_in, -np.hypot(dr, dz))


@dataclass(frozen=True)
class TrajectorySpec:
    """The path through the required poses: a jerk-limited point-to-point profile
    (``limits``, sampled every ``dt`` seconds) or timed samples (``times`` (K,) s and
    ``values`` (K, k) in the task's pose coordinates). ``waypoints`` (W, k) with their
    ``waypoint_coordinates``: the poses the profiled path runs through, in order, instead of
    the required poses (e.g. a path that returns to poses it has visited; NaN leaves a
    coordinate at home, as in the poses)."""

    limits: MotionLimits | None = None
    dt: float = 0.01
    times: np.ndarray | None = field(default=None, compare=False)
    values: np.ndarray | None = field(default=None, compare=False)
    coordinates: tuple = ()
    waypoints: np.ndarray | None = field(default=None, compare=False)
    waypoint_coordinates: tuple = ()

    def __post_init__(self):
        if self.limits is None and self.times is None:
            raise TaskError("trajectory: give motion limits (speed, acceleration, ...) or a file of timed poses")
        if self.limits is not None:
            object.__setattr__(self, "dt", _num("trajectory.dt", self.dt, "a time step > 0 (s)", low=0.0,
                                                strict=True))
        key = None
        if self.waypoints is not None:
            if self.limits is None:
                raise TaskError("trajectory.waypoints: a file of timed poses takes no waypoints")
            W = np.array(self.waypoints, dtype=float)
            if W.ndim != 2 or len(W) < 2 or (self.waypoint_coordinates and W.shape[1] != len(self.waypoint_coordinates)) \
                    or np.any(np.isinf(W)):
                raise TaskError("trajectory.waypoints: give at least 2 poses, one finite value per named coordinate")
            W.setflags(write=False)
            object.__setattr__(self, "waypoints", W)
            object.__setattr__(self, "waypoint_coordinates", tuple(self.waypoint_coordinates))
            key = (self.waypoint_coordinates, W.tobytes())
        #: What identifies the waypoints in a cache key (None: the path runs through the poses).
        object.__setattr__(self, "_waypoints_key", key)
        if self.times is not None:
            t = np.asarray(self.times, dtype=float)
            if t.ndim != 1 or len(t) < 3 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
                raise TaskError("trajectory.file: the time column must hold at least 3 increasing finite times (s)")


def _as_trajectory(where, v, coordinates=None):
    if v is None or isinstance(v, TrajectorySpec):
        return v
    if isinstance(v, Mapping):
        keys = {"speed", "acceleration", "angular_speed", "angular_acceleration", "jerk_time", "limits", "timing",
                "step"}
        unknown = sorted(set(v) - keys - {"dt", "waypoints"})
        if unknown:
            raise TaskError(f"{where}.{unknown[0]}: unknown key; allowed: "
                            f"{', '.join(sorted(keys | {'dt', 'waypoints'}))}")
        kw = {k: v[k] for k in keys if k in v}
        if kw.get("timing") == "sampled":  # phases rounded to the sample step unless another is given
            kw.setdefault("step", v.get("dt", 0.01))
        try:
            lim = MotionLimits(**kw)
        except TypeError as e:
            raise TaskError(f"{where}: give speed and acceleration (SI) ({e})") from None
        except ValueError as e:
            raise TaskError(f"{where}.{e}") from None
        if v.get("waypoints") is not None:  # columns as the poses'
            try:
                W = np.array(v["waypoints"], dtype=float)
            except (TypeError, ValueError):
                raise TaskError(f"{where}.waypoints: give an (M, k) array of poses like the poses") from None
            return TrajectorySpec(lim, v.get("dt", 0.01), waypoints=W, waypoint_coordinates=tuple(coordinates or ()))
        return TrajectorySpec(lim, v.get("dt", 0.01))
    raise TaskError(f"{where}: give a mapping of motion limits or a TrajectorySpec, got {v!r}")


# ---------------------------------------------------------------------------------------------
# the task
# ---------------------------------------------------------------------------------------------
class Task:
    """What a design must do (see the module documentation for frames and conventions).

    ``poses``: (N, k) array of required poses, columns ``coordinates`` (default: the
    mechanism's own task coordinates in its order, of the platform frame); NaN in a column
    leaves that coordinate at home. ``tool``: offset (3,) m in the platform frame, or a
    :class:`Tool`; ``tool_yaw`` (rad). ``placement``: a :class:`Placement` or a mapping
    ``{offset, yaw, hanging}``. ``convention``: Euler convention of ``alpha, beta, gamma``
    (default ``xyz``). ``frame``: "tool" or "platform" (default: "platform" for an unnamed
    array, "tool" otherwise). ``wrench`` (6,) or (N, 6) N and N m at the tool point;
    ``wrench_frame`` "task" | "base" | "tool"; ``wrench_signs``. ``payload``: a
    :class:`Payload` or a mapping ``{mass, com, inertia}``. ``gravity`` (m/s^2, along -z of
    ``W``; or a vector (3,) in ``W``). ``trajectory``: a :class:`TrajectorySpec` or a mapping of motion limits (SI) with
    ``dt``. ``space``: a :class:`Space` or a mapping. ``floors``: {"condition": {"max": 500},
    "singularity_margin": {"min": 0.05}, "lti": {"min": 0.5}} that hold at every pose and path
    sample. ``order``: "given" or "nearest" (greedy nearest neighbour from the first pose).
    ``leg_density`` (kg/m^3, default 0: massless legs): the legs' own masses in the inverse
    dynamics and the static forces, every leg a solid rod of the leg diameter
    (:func:`parasynth.measures.task.leg_inertia`).
    ``pose_tolerance``: the largest residual (fraction of the length scale) of a platform pose
    the mechanism reaches only in the least-squares sense (default 1e-6; a mechanism whose
    orientation is coupled to its position, e.g. the 5-PUS/UPU, reaches a placed pose only
    approximately).
    """

    def __init__(self, poses=None, *, coordinates=None, tool=None, tool_yaw: float = 0.0, wrench=None,
                 payload=None, placement=None, convention: str = "xyz", frame: str | None = None,
                 wrench_frame: str = "task", wrench_signs: bool = False, gravity: float = G0, trajectory=None,
                 space=None, floors=None, order: str = "given", leg_diameter: float | None = None,
                 coordinate_kinds=None, where: str = "task", pose_tolerance: float = 1e-6, leg_density: float = 0.0):
        if poses is None:
            raise TaskError("task.poses: give the required poses (an (N, k) array)")
        try:
            P = np.array(poses, dtype=float) if not isinstance(poses, (str, bytes, Mapping)) else None
        except (TypeError, ValueError):
            P = None
        if P is not None and P.ndim == 1:
            P = P[None, :]
        if P is None or P.ndim != 2 or P.shape[0] == 0 or P.shape[1] == 0:
            got = np.shape(poses) if P is not None else repr(poses)
            raise TaskError(f"task.poses: give an (N, k) array of numbers, got {got}")
        if np.any(np.isinf(P)):
            raise TaskError("task.poses: coordinates must be finite (NaN leaves a coordinate at home)")
        if coordinates is not None:
            coordinates = tuple(coordinates)
            if len(coordinates) != P.shape[1] or not all(isinstance(c, str) for c in coordinates) \
                    or len(set(coordinates)) != len(coordinates):
                raise TaskError(f"task.poses: coordinates must name each of the {P.shape[1]} columns once, "
                                f"got {coordinates!r}")
        self.poses = P
        self.poses.setflags(write=False)
        self.coordinates = coordinates
        self.coordinate_kinds = dict(coordinate_kinds or {})
        #: The key path of the task in its file, for the messages of a task meeting a mechanism.
        self.where = str(where)
        #: Largest residual (fraction of the length scale; rotations in rad) of a platform pose
        #: the mechanism reaches only in the least-squares sense.
        self.pose_tolerance = _num("task.pose_tolerance", pose_tolerance, "a fraction > 0 of the length scale",
                                   low=0.0, strict=True)
        if convention not in TASK_CONVENTIONS:
            raise TaskError(f"task.convention: unknown Euler convention {convention!r}; allowed: "
                            f"{', '.join(TASK_CONVENTIONS)}")
        self.convention = convention
        if frame is None:
            frame = "platform" if coordinates is None else "tool"
        if frame not in ("tool", "platform"):
            raise TaskError(f"task.frame: must be tool or platform, got {frame!r}")
        self.frame = frame
        if isinstance(tool, Tool):
            self.tool = dataclasses.replace(tool, yaw=tool.yaw + float(tool_yaw)) if tool_yaw else tool
        else:
            self.tool = Tool((0.0, 0.0, 0.0) if tool is None else tool, tool_yaw)
        if isinstance(placement, Placement) or placement is None:
            self.placement = placement or Placement()
        elif isinstance(placement, Mapping):
            unknown = sorted(set(placement) - {"offset", "yaw", "hanging"})
            if unknown:
                raise TaskError(f"task.placement.{unknown[0]}: unknown key; allowed: offset, yaw, hanging")
            self.placement = Placement(**placement)
        else:
            raise TaskError(f"task.placement: give a Placement or a mapping {{offset, yaw, hanging}}, "
                            f"got {placement!r}")
        N = P.shape[0]
        if wrench is None:
            self.wrench = None
        else:
            try:
                w = np.array(wrench, dtype=float) if not isinstance(wrench, (str, Mapping)) else None
            except (TypeError, ValueError):
                w = None
            if w is None or w.shape not in ((6,), (N, 6)) or not np.all(np.isfinite(w)):
                raise TaskError(f"task.wrench: give [fx, fy, fz, mx, my, mz] (N, N m) or one per pose ({N}, 6), "
                                f"got {np.shape(w) if w is not None else wrench!r}")
            w.setflags(write=False)
            self.wrench = w
        if wrench_frame not in ("task", "base", "tool"):
            raise TaskError(f"task.loads.frame: must be task, base or tool, got {wrench_frame!r}")
        self.wrench_frame = wrench_frame
        if not isinstance(wrench_signs, bool):
            raise TaskError(f"task.loads.signs: give true or false, got {wrench_signs!r}")
        self.wrench_signs = wrench_signs
        if payload is None or isinstance(payload, Payload):
            self.payload = payload or Payload()
        elif isinstance(payload, Mapping):
            unknown = sorted(set(payload) - {"mass", "com", "inertia"})
            if unknown:
                raise TaskError(f"task.payload.{unknown[0]}: unknown key; allowed: mass, com, inertia")
            self.payload = Payload(**payload)
        else:
            raise TaskError(f"task.payload: give a mapping {{mass, com, inertia}}, got {payload!r}")
        if isinstance(gravity, (list, tuple, np.ndarray)):
            self.gravity = np.array(_vec("task.loads.gravity", gravity, 3, "m/s^2"))
        else:
            self.gravity = _num("task.loads.gravity", gravity, "a gravity >= 0 (m/s^2) or a vector in W", low=0.0)
        self.trajectory = _as_trajectory("task.trajectory", trajectory, coordinates)
        tr = self.trajectory
        if tr is not None and tr.waypoints is not None and tr.waypoints.shape[1] != P.shape[1] \
                and not tr.waypoint_coordinates:
            raise TaskError(f"task.trajectory.waypoints: {tr.waypoints.shape[1]} columns; the poses have {P.shape[1]}")
        if space is None or isinstance(space, Space):
            self.space = space
        elif isinstance(space, Mapping):
            unknown = sorted(set(space) - {f.name for f in dataclasses.fields(Space)})
            if unknown:
                raise TaskError(f"task.space.{unknown[0]}: unknown key; allowed: "
                                f"{', '.join(f.name for f in dataclasses.fields(Space))}")
            self.space = Space(**space)
        else:
            raise TaskError(f"task.space: give a Space or a mapping, got {space!r}")
        self.floors = _check_floors("task.floors", floors or {})
        if order not in ("given", "nearest"):
            raise TaskError(f"task.poses.order: must be given or nearest, got {order!r}")
        self.order = order
        if order == "nearest":  # the poses (and per-pose wrenches) in nearest-neighbour order
            idx = _nearest_order(self.poses)
            self.poses = self.poses[idx]
            self.poses.setflags(write=False)
            if self.wrench is not None and self.wrench.ndim == 2:
                self.wrench = self.wrench[idx]
                self.wrench.setflags(write=False)
        self.leg_diameter = None if leg_diameter is None else _num("task.space.leg_diameter", leg_diameter,
                                                                   "a diameter >= 0 (m)", low=0.0)
        #: Density (kg/m^3) of the legs as solid rods in the inverse dynamics; 0: massless legs.
        self.leg_density = _num("task.loads.leg_density", leg_density, "a density >= 0 (kg/m^3)", low=0.0)
        #: Mechanism-independent work (the poses in ``W``, the path's samples in ``W``), shared
        #: by the task's copies (:meth:`with_settings` of a study's designs): see :meth:`_shared`.
        self._cache = {}

    # -- copies ------------------------------------------------------------------------------------
    def _copy(self, **changes) -> "Task":
        new = object.__new__(Task)
        new.__dict__.update(self.__dict__)
        new.__dict__.update(changes)
        return new

    #: Settings :meth:`with_settings` accepts (SI: m and rad).
    SETTINGS = ("placement.x", "placement.y", "placement.z", "placement.yaw", "tool.x", "tool.y", "tool.z",
                "tool.yaw")

    def with_settings(self, settings: Mapping) -> "Task":
        """A new task with some placement and tool values changed (design variables of a
        study), e.g. ``{"placement.z": 0.1, "placement.yaw": 0.3, "tool.yaw": 0.5}`` (m, rad)."""
        if not isinstance(settings, Mapping):
            raise TaskError(f"task settings: give a mapping {{name: value}}, got {settings!r}")
        pl, tl = self.placement, self.tool
        po, to = list(pl.offset), list(tl.offset)
        pyaw, tyaw = pl.yaw, tl.yaw
        for k, v in settings.items():
            if k not in self.SETTINGS:
                raise TaskError(f"task.{k}: not a task setting; allowed: {', '.join(self.SETTINGS)}")
            v = _num(f"task.{k}", v, "a number (SI: m or rad)")
            part, _, comp = k.partition(".")
            if comp == "yaw":
                if part == "placement":
                    pyaw = v
                else:
                    tyaw = v
            else:
                (po if part == "placement" else to)["xyz".index(comp)] = v
        return self._copy(placement=Placement(tuple(po), pyaw, pl.hanging), tool=Tool(tuple(to), tyaw))

    #: The most poses :meth:`refined` makes of a grid.
    MAX_REFINED = 200_000

    def refined(self, factor: int = 3, rate: int = 10) -> "Task":
        """The denser task a recommended design is re-checked on (docs/verification.md). With a
        trajectory the required poses are **kept** (the path through them is what is followed;
        a refined grid would be another path) and a profiled path is sampled ``rate`` times as
        often (a file of timed poses is kept as it is). Without a trajectory, poses that form a
        full grid (every combination of each coordinate's distinct values) are refined
        ``factor`` times per axis (``(n - 1) * factor + 1`` values between the same extremes; a
        smaller factor where the grid would exceed :attr:`MAX_REFINED` poses), other pose lists
        kept as they are. :meth:`refinement` says which in words."""
        new_poses, traj, _ = self._refine_plan(factor, rate)
        changes = {"poses": new_poses, "trajectory": traj}
        if self.wrench is not None and self.wrench.ndim == 2 and new_poses is not self.poses:
            raise TaskError("task: a per-pose wrench cannot be refined to new poses; give a constant wrench")
        return self._copy(**changes)

    def refinement(self, factor: int = 3, rate: int = 10) -> str:
        """What :meth:`refined` does to this task, in words (e.g. "the path at 10x the sample
        rate, its 342 poses kept"), for the verification's messages."""
        return self._refine_plan(factor, rate)[2]

    def _refine_plan(self, factor, rate):
        poses = self.poses
        traj = self.trajectory
        n = len(poses)
        if traj is not None:
            if traj.limits is None:
                return poses, traj, f"the timed path and its {n} poses kept as they are"
            if rate > 1:
                dense = dataclasses.replace(traj, dt=traj.dt / rate)
                return poses, dense, f"the path at {int(rate)}x the sample rate, its {n} poses kept"
            return poses, traj, f"the path and its {n} poses kept"
        grid = None
        if n and np.all(np.isfinite(poses)):
            vals = [np.unique(poses[:, j]) for j in range(poses.shape[1])]
            if math.prod(len(v) for v in vals) == n:
                grid = vals
        if grid is None or factor <= 1 or all(len(v) == 1 for v in grid):
            return poses, traj, f"its {n} poses kept (not a full grid)" if grid is None else f"its {n} poses kept"
        f = int(factor)
        while f > 1 and math.prod((len(v) - 1) * f + 1 for v in grid) > self.MAX_REFINED:
            f -= 1
        if f <= 1:
            return poses, traj, f"its {n} poses kept (a refined grid would exceed {self.MAX_REFINED} poses)"
        axes = [np.linspace(v[0], v[-1], (len(v) - 1) * f + 1) if len(v) > 1 else v for v in grid]
        new_poses = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(axes), -1).T.copy()
        new_poses.setflags(write=False)
        return new_poses, traj, f"grid poses {f}x per axis ({n} -> {len(new_poses)})"

    def __repr__(self) -> str:
        return (f"<Task {self.poses.shape[0]} poses {self.coordinates or '(mechanism order)'} frame={self.frame}"
                f"{' trajectory' if self.trajectory else ''}>")

    @property
    def n_poses(self) -> int:
        return int(self.poses.shape[0])

    # -- meeting a mechanism -----------------------------------------------------------------------
    def _mode(self, mech) -> str:
        """'own' (the mechanism's own task coordinates) or 'full' (x, y, z, alpha, beta, gamma)."""
        if self.coordinates is None:
            if self.poses.shape[1] != mech.n_task:
                raise TaskError(f"{self.where}.poses: {self.poses.shape[1]} columns given; {mech.name} has "
                                f"{mech.n_task} task "
                                f"coordinates {', '.join(mech.task_coordinates)}")
            return "own"
        if mech.n_task == 6:
            bad = [c for c in self.coordinates if c not in STANDARD_NAMES]
            if bad:
                raise TaskError(f"{self.where}.poses.{bad[0]}: not a pose coordinate of a 6-freedom mechanism; "
                                f"allowed: "
                                f"{', '.join(STANDARD_NAMES)}")
            return "full"
        bad = [c for c in self.coordinates if c not in mech.task_coordinates]
        if bad:
            raise TaskError(f"{self.where}.poses.{bad[0]}: {mech.name} has no freedom {bad[0]!r} (it has "
                            f"{mech.n_task}: {', '.join(mech.task_coordinates)}; a mechanism with fewer than 6 "
                            f"freedoms takes poses in its own task coordinates)")
        for c, kind in self.coordinate_kinds.items():
            want = "angle" if c in mech.angular_coordinates else "length"
            if c in mech.task_coordinates and kind != want:
                raise TaskError(f"{self.where}.poses.{c}: {c!r} is a{'n' if want == 'angle' else ''} {want} "
                                f"coordinate of "
                                f"{mech.name}, given as a{'n' if kind == 'angle' else ''} {kind}")
        return "own"

    def _frame_pose_W(self, mech, mode):
        """Poses (p, R) in ``W`` of the frame the poses describe, (N, 3) and (N, 3, 3)."""
        if mode == "own":
            X = self._own_coordinates(mech)
            return mech.pose(X)
        if self._all_named():  # the poses alone: the same for every mechanism, computed once
            return self._shared(("W", self.convention, self.coordinates),
                                lambda: _read_only(self._standard_pose_W(None)))
        return self._standard_pose_W(self._home_standard(mech))

    def _all_named(self) -> bool:
        """Whether the poses give every standard coordinate (no NaN): their poses in ``W`` do not
        depend on the mechanism's home."""
        ok = self.__dict__.get("_named")
        if ok is None or ok[0] is not self.poses:
            full = self.coordinates is not None and set(self.coordinates) >= set(STANDARD_NAMES)
            ok = (self.poses, bool(full and not np.isnan(self.poses).any()))
            self.__dict__["_named"] = ok
        return ok[1]

    def _standard_pose_W(self, home):
        full = np.zeros((self.n_poses, 6)) if home is None else np.tile(home, (self.n_poses, 1))
        for j, c in enumerate(self.coordinates):
            col = self.poses[:, j]
            k = STANDARD_NAMES.index(c)
            full[:, k] = col if home is None else np.where(np.isnan(col), full[:, k], col)
        return full[:, :3], euler_to_matrix(self.convention, full[:, 3:])

    def _shared(self, key, fn):
        """``fn()`` computed once for this task's poses and ``key`` (mechanism-independent work),
        kept in the cache the task's copies share; recomputed for copies with other poses."""
        cache = self.__dict__.get("_cache")
        if cache is None:  # a task made without __init__
            cache = self.__dict__["_cache"] = {}
        hit = cache.get(key)
        if hit is not None and hit[0] is self.poses:
            return hit[1]
        if len(cache) > 16:
            cache.clear()
        val = fn()
        cache[key] = (self.poses, val)
        return val

    def _own_coordinates(self, mech, P=None, names=None) -> np.ndarray:
        """The mechanism's coordinates of the poses (or of ``P`` with columns ``names``)."""
        if P is None:
            P, names = self.poses, self.coordinates
        X = np.tile(mech.home, (len(P), 1))
        names = names or mech.task_coordinates
        for j, c in enumerate(names):
            if c not in mech.task_coordinates:
                raise TaskError(f"{self.where}.trajectory.waypoints.{c}: {mech.name} has no freedom {c!r} (it has "
                                f"{', '.join(mech.task_coordinates)})")
            k = mech.task_coordinates.index(c)
            X[:, k] = np.where(np.isnan(P[:, j]), X[:, k], P[:, j])
        return X

    def _path_poses(self):
        """(poses, their coordinate names) the profiled path runs through: the trajectory's
        waypoints, else the required poses."""
        tr = self.trajectory
        if tr is not None and tr.waypoints is not None:
            return tr.waypoints, tr.waypoint_coordinates
        return self.poses, self.coordinates

    def _home_standard(self, mech) -> np.ndarray:
        """The home pose of the task's frame in ``W`` as x, y, z, alpha, beta, gamma."""
        p, R = mech.pose(mech.home)
        p, R = self.platform_to_frame(p[None], R[None])
        return np.concatenate([p[0], matrix_to_euler(self.convention, R[0])])

    def frame_to_platform(self, p, R):
        """Platform poses in ``B`` for poses ``(p, R)`` in ``W`` of the task's frame."""
        if self.frame == "tool" and not self.tool.identity:
            R = _rmul(R, self.tool.R.T)
            p = p - R @ np.array(self.tool.offset)
        if self.placement.identity:
            return p, R
        Rw, pw = self.placement.R, self.placement.p
        return pw + p @ Rw.T, _lmul(Rw, R)

    def platform_to_frame(self, p, R):
        """Poses in ``W`` of the task's frame for platform poses ``(p, R)`` in ``B``."""
        Rw, pw = self.placement.R, self.placement.p
        p = (p - pw) @ Rw
        R = _lmul(Rw.T, R)
        if self.frame == "tool":
            p = p + R @ np.array(self.tool.offset)
            R = _rmul(R, self.tool.R)
        return p, R

    def tool_points(self, p, R) -> np.ndarray:
        """Tool points (N, 3) in ``B`` for platform poses ``(p, R)`` in ``B``."""
        return p + R @ np.array(self.tool.offset)

    def check(self, mech) -> None:
        """Raise :class:`TaskError` where the task does not fit ``mech``: a pose coordinate it
        lacks, a platform pose outside its freedoms, an installation space without the home
        pose's bodies."""
        self.platform_poses(mech)
        if self.space is not None:
            c = self.space_clearance(mech, mech.home[None, :])
            if not np.all(c >= 0):
                raise TaskError(f"{self.where}.space: the mechanism's bodies at its home pose are not inside the "
                                f"installation space (clearance {format_quantity(float(np.min(c)), 'length')})")

    def platform_poses(self, mech) -> np.ndarray:
        """The mechanism's task coordinates (N, d) of the platform for every required pose."""
        mode = self._mode(mech)
        if mode == "own":
            if self.placement.identity:
                return self._own_coordinates(mech)
            own = self._as_platform()
            return own.coordinates_of(mech, *own._frame_pose_W(mech, mode))
        return self.coordinates_of(mech, *self._frame_pose_W(mech, mode))

    def _as_platform(self) -> "Task":
        """This task with its poses read as the platform's (own coordinates describe the
        platform: a tool on a mechanism with fewer than 6 freedoms only places the tool point)."""
        return self if self.frame == "platform" else self._copy(frame="platform")

    def frame_pose_W(self, mech):
        """Poses (p, R) in ``W`` of the task's frame at every required pose."""
        return self._frame_pose_W(mech, self._mode(mech))

    def coordinates_of(self, mech, p, R, guess=None, where: str | None = None) -> np.ndarray:
        """Task coordinates (N, d) of ``mech`` for poses ``(p, R)`` in ``W`` of the task's frame."""
        mode = self._mode(mech)
        where = f"{self.where}.poses" if where is None else where
        pb, Rb = self.frame_to_platform(p, R)
        std = standard_parametrisation(mech)
        if std is not None:  # the mechanism's coordinates are a position and named Euler angles: exact
            return _standard_coordinates(mech, std, pb, Rb)
        if guess is None:
            guess = self._guess(mech, pb, Rb, mode)
        return solve_pose(mech, pb, Rb, guess, where, tol=self.pose_tolerance)

    def _guess(self, mech, pb, Rb, mode):
        N = pb.shape[0]
        if mode == "own":
            return self._own_coordinates(mech) if N == self.n_poses else np.tile(mech.home, (N, 1))
        X = np.tile(mech.home, (N, 1))
        conv = getattr(getattr(getattr(mech, "description", None), "task", None), "convention", None)
        tc = mech.task_coordinates
        names = getattr(getattr(getattr(mech, "description", None), "task", None), "angles", None)
        if conv in TASK_CONVENTIONS and all(c in tc for c in ("x", "y", "z")):
            for k, c in enumerate("xyz"):
                X[:, tc.index(c)] = pb[:, k]
            ang = [a for a in tc if a in mech.angular_coordinates]
            if len(ang) == 3:
                E = matrix_to_euler(conv, Rb)
                for k, a in enumerate(_angle_order(names, ang)):
                    X[:, tc.index(a)] = E[:, k]
        return X

    # -- installation space ------------------------------------------------------------------------
    def space_clearance(self, mech, X, diameter: float | None = None) -> np.ndarray:
        """Smallest clearance (N,) (m, >= 0 inside) of every body at platform poses ``X`` (the
        mechanism's task coordinates) to the installation space (and, when moving parts may
        not pass it, to the base plane): base anchors and the legs' base and platform joint
        centres (leg segments of ``diameter``, default ``leg_diameter`` of the task or the
        mechanism's parameter ``leg_diameter``, else 0: the clearance of a segment in a convex
        space is the smaller of its ends'; a crank from its pivot to its tip likewise), the
        platform anchors and a 16-point circle through
        the farthest anchor in the platform plane (the platform as a disc). NaN where
        unreachable. ``inf`` without a space."""
        if self.space is None:
            return np.full(len(X), np.inf)
        d = self._leg_diameter(mech) if diameter is None else float(diameter)
        Xa = np.atleast_2d(np.asarray(X, dtype=float))
        _, states, p = mech.leg_states(Xa)
        _, R = mech.pose(Xa)
        reach = np.logical_and.reduce([st.reachable for st in states])
        Rw, pw = self.placement.R, self.placement.p

        def toW(x):
            return (x - pw) @ Rw

        fixed = np.broadcast_to(np.array([np.asarray(leg.base, dtype=float) for leg in mech.legs]),
                                (len(Xa), len(mech.legs), 3))  # the base anchors (a crank's pivot)
        ends = np.concatenate([fixed, np.stack([st.base_point for st in states] + [st.platform_point for st in states],
                                               axis=1)], axis=1)
        c_leg = self.space.clearance(toW(ends)) - 0.5 * d
        # the platform as a disc through its farthest anchor
        anchors = np.stack([leg.platform for leg in mech.legs], axis=0) if hasattr(mech.legs[0], "platform") else None
        rad = float(np.max(np.linalg.norm(np.asarray(anchors)[:, :2], axis=1))) if anchors is not None else 0.0
        th = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        circ = np.stack([rad * np.cos(th), rad * np.sin(th), np.zeros_like(th)], axis=1)
        disc = p[:, None, :] + np.einsum("nij,kj->nki", R, circ)
        c_plat = self.space.clearance(toW(disc))
        c = np.minimum(c_leg.min(axis=1), c_plat.min(axis=1))
        if not self.space.base_plane:
            ph, _ = mech.pose(mech.home)
            side = 1.0 if ph[2] >= 0 else -1.0
            moving = np.concatenate([np.stack([st.platform_point for st in states], axis=1), disc], axis=1)
            c = np.minimum(c, side * moving[..., 2].min(axis=1) if side > 0 else (-moving[..., 2]).min(axis=1))
        return np.where(reach, c, np.nan)

    def line_clearance(self, mech, p, R, diameter: float | None = None) -> np.ndarray:
        """:meth:`space_clearance` for a mechanism whose legs all run straight from a fixed base
        joint centre (the anchor) to the platform anchor (SPS and UPS legs), from the platform
        poses ``p`` (N, 3) and ``R`` (N, 3, 3) in ``B`` (every pose taken as reachable): the same
        bodies and arithmetic, without solving the legs, and the fixed anchors' clearance
        computed once. ``inf`` without a space."""
        N = len(p)
        if self.space is None:
            return np.full(N, np.inf)
        d = self._leg_diameter(mech) if diameter is None else float(diameter)
        Rw, pw = self.placement.R, self.placement.p
        base = np.array([np.asarray(leg.base, dtype=float) for leg in mech.legs])
        plat = np.array([np.asarray(leg.platform, dtype=float) for leg in mech.legs])
        rad = float(np.max(np.linalg.norm(plat[:, :2], axis=1)))
        th = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        circ = np.stack([rad * np.cos(th), rad * np.sin(th), np.zeros_like(th)], axis=1)
        # the platform anchors, then the rim: in B (N, 3, n + 16), then in W
        local = np.concatenate([plat, circ], axis=0)
        XB = R @ local.T
        XB += p[:, :, None]
        XW = np.matmul(Rw.T, XB - pw[:, None])
        n = len(plat)
        c_fixed = float(np.min(self.space.clearance((base - pw) @ Rw))) - 0.5 * d
        c = np.minimum(self._min_clearance(XW[:, :, :n]) - 0.5 * d, self._min_clearance(XW[:, :, n:]))
        c = np.minimum(c, c_fixed)
        if not self.space.base_plane:
            ph, _ = mech.pose(mech.home)
            z = XB[:, 2, :]
            c = np.minimum(c, z.min(axis=1) if ph[2] >= 0 else (-z).min(axis=1))
        return c

    def _min_clearance(self, X) -> np.ndarray:
        """(N,) the smallest clearance of the points ``X`` (N, 3, k) in ``W`` of each pose. In a
        box, when every point is inside it is the smallest distance of the points' per-axis
        extremes to the faces; poses with a point outside (and a cylinder) take the points'
        signed distances (:meth:`Space.clearance`)."""
        sp = self.space
        if sp.shape != "box":
            return sp.clearance(np.swapaxes(X, 1, 2)).min(axis=1)
        lo, hi = np.array(sp.low), np.array(sp.high)
        d = np.minimum(X.min(axis=2) - lo, hi - X.max(axis=2)).min(axis=1)
        out = d < 0
        if out.any():
            d[out] = sp.clearance(np.swapaxes(X[out], 1, 2)).min(axis=1)
        return d

    def _leg_diameter(self, mech) -> float:
        if self.leg_diameter is not None:
            return self.leg_diameter
        v = getattr(mech.params, "leg_diameter", None) if not isinstance(mech.params, Mapping) else \
            mech.params.get("leg_diameter")
        try:
            return float(v) if v is not None else 0.0
        except (TypeError, ValueError):
            return 0.0

    # -- loads ---------------------------------------------------------------------------------------
    def gravity_vector(self) -> np.ndarray:
        """Gravity (m/s^2) in ``B``: ``gravity`` along -z of ``W`` (or the vector given in ``W``)."""
        g = self.gravity if isinstance(self.gravity, np.ndarray) else np.array([0.0, 0.0, -self.gravity])
        return self.placement.R @ g

    def wrench_components(self, R, n: int | None = None) -> np.ndarray | None:
        """The external wrench at the tool point in ``B``, (N, 6), for platform orientations
        ``R`` (N, 3, 3) in ``B`` (per-pose wrenches need N = the number of poses)."""
        if self.wrench is None:
            return None
        N = R.shape[0]
        w = np.broadcast_to(self.wrench, (N, 6)) if self.wrench.ndim == 1 else self.wrench
        if w.shape[0] != N:
            raise TaskError(f"{self.where}.wrench: {w.shape[0]} per-pose wrenches for {N} samples")
        if self.wrench_frame == "task":
            Rf = np.broadcast_to(self.placement.R, (N, 3, 3))
        elif self.wrench_frame == "base":
            Rf = np.broadcast_to(np.eye(3), (N, 3, 3))
        else:
            Rf = R @ self.tool.R
        return np.concatenate([np.einsum("nij,nj->ni", Rf, w[:, :3]), np.einsum("nij,nj->ni", Rf, w[:, 3:])], 1)

    # -- trajectory ----------------------------------------------------------------------------------
    def path(self, mech):
        """The path through the required poses for ``mech``: :class:`TaskPath` (sample times,
        the mechanism's task coordinates X, rates Xd and accelerations Xdd of every sample, the
        tool's speed and acceleration). None without a trajectory."""
        if self.trajectory is None:
            return None
        mode = self._mode(mech)
        tr = self.trajectory
        if tr.times is not None:
            return self._timed_path(mech, mode)
        if mode == "full":
            return self._full_path(mech)
        X = self._own_coordinates(mech, *self._path_poses())
        lin = np.array([c not in mech.angular_coordinates for c in mech.task_coordinates])
        dX = np.diff(X, axis=0)
        size = (lambda d: np.abs(d).max(axis=1, initial=0.0)) if tr.limits.limits == "per_coordinate" else \
            (lambda d: np.linalg.norm(d, axis=1))
        ps = sample_path(size(dX[:, lin]), size(dX[:, ~lin]), tr.limits, tr.dt)
        seg, s = ps.segment, ps.s
        dX = X[seg + 1] - X[seg]
        own = self._as_platform()
        if self.placement.identity:
            # a straight line in the mechanism's own coordinates
            return TaskPath(ps.t, X[seg] + s[:, None] * dX, dX * ps.sd[:, None], dX * ps.sdd[:, None], ps)

        def coords(sv):
            Xs = X[seg] + sv[:, None] * dX
            return own.coordinates_of(mech, *mech.pose(Xs), guess=Xs, where=f"{self.where}.trajectory")

        return _chain(ps, coords(s), coords(s + _H), coords(s - _H))

    def _full_samples(self, mech):
        """The path's samples in ``W`` (mechanism-independent but for the home values of the
        coordinates not named), cached on the task."""
        home = None if self._all_named() else tuple(np.round(self._home_standard(mech), 12))
        tr = self.trajectory
        key = ("path", home, self.convention, self.coordinates, tr.limits, tr.dt, tr._waypoints_key)
        return self._shared(key, lambda: self._sample_full(mech))

    def _sample_full(self, mech):
        """(samples, poses in W at s and s +- _H, and the frame's velocity, angular velocity,
        acceleration and angular acceleration in W at every sample)."""
        lim = self.trajectory.limits
        if lim.limits == "per_coordinate":
            return self._sample_full_coordinates(mech)
        pW, RW = self._path_pose_W(mech)
        dist = np.linalg.norm(np.diff(pW, axis=0), axis=1)
        rv_all = rotation_log(np.swapaxes(RW[:-1], 1, 2) @ RW[1:])
        ps = sample_path(dist, np.linalg.norm(rv_all, axis=1), lim, self.trajectory.dt)
        seg, s = ps.segment, ps.s
        dp, rv, Ra = pW[seg + 1] - pW[seg], rv_all[seg], RW[seg]
        at = {k: (pW[seg] + sv[:, None] * dp, Ra @ rotation_exp(sv[:, None] * rv))
              for k, sv in (("0", s), ("+", s + _H), ("-", s - _H))}
        axis = np.einsum("njk,nk->nj", Ra, rv)  # rotation axis times angle, in W
        for v in at.values():
            _read_only(v)
        sd, sdd = ps.sd[:, None], ps.sdd[:, None]
        return ps, at, _read_only((dp * sd, axis * sd, dp * sdd, axis * sdd))

    def _sample_full_coordinates(self, mech):
        """:meth:`_sample_full` with the limits on each coordinate: every coordinate (x, y, z
        and the convention's three angles, read in W) moves on a straight line between two
        poses (an angle by its change wrapped to (-pi, pi]), all on the progress of the
        coordinate that needs the longest time."""
        pW, RW = self._path_pose_W(mech)
        P, names = self._path_poses()
        if names and all(a in names for a in _ANGLES) and not np.isnan(P).any():
            # the angles as given (the same rotations, on the given branch)
            E = np.stack([P[:, names.index(a)] for a in _ANGLES], axis=1)
        else:
            E = matrix_to_euler(self.convention, RW)
        dp_all = np.diff(pW, axis=0)
        dE_all = np.diff(E, axis=0)
        dE_all = (dE_all + np.pi) % (2 * np.pi) - np.pi
        dE_all = np.where(np.isclose(dE_all, -np.pi), np.pi, dE_all)
        ps = sample_path(np.abs(dp_all).max(axis=1) if len(dp_all) else np.zeros(0),
                         np.abs(dE_all).max(axis=1) if len(dE_all) else np.zeros(0),
                         self.trajectory.limits, self.trajectory.dt)
        seg, s = ps.segment, ps.s
        dp, dE = dp_all[seg], dE_all[seg]
        at = {}
        for k, sv in (("0", s), ("+", s + _H), ("-", s - _H)):
            at[k] = _read_only((pW[seg] + sv[:, None] * dp, euler_to_matrix(self.convention, E[seg] + sv[:, None] * dE)))
        sd, sdd = ps.sd[:, None], ps.sdd[:, None]
        Ed, Edd = dE * sd, dE * sdd
        # omega = sum_i q_i' u_i (u_i: the i-th axis of the sequence, turned by the angles before
        # it); alpha = sum_i q_i'' u_i + sum_i q_i' (omega_<i x u_i)
        U = euler_rate_map(self.convention, E[seg] + s[:, None] * dE)
        w = np.einsum("nij,nj->ni", U, Ed)
        al = np.einsum("nij,nj->ni", U, Edd)
        w_before = np.zeros_like(w)
        for i in range(3):
            ui = U[:, :, i]
            al += Ed[:, i:i + 1] * _cross(w_before, ui)
            w_before = w_before + Ed[:, i:i + 1] * ui
        return ps, at, _read_only((dp * sd, w, dp * sdd, al))

    def _path_pose_W(self, mech):
        """Poses (p, R) in ``W`` of the task's frame at the poses the path runs through."""
        tr = self.trajectory
        if tr.waypoints is None:
            return self._frame_pose_W(mech, "full")
        names = tr.waypoint_coordinates
        bad = [c for c in names if c not in STANDARD_NAMES]
        if bad:
            raise TaskError(f"{self.where}.trajectory.waypoints.{bad[0]}: not a pose coordinate of a 6-freedom "
                            f"mechanism; allowed: {', '.join(STANDARD_NAMES)}")
        sub = self._copy(poses=tr.waypoints, coordinates=names, _cache={})
        home = None if sub._all_named() else self._home_standard(mech)
        return sub._standard_pose_W(home)

    def _full_path(self, mech):
        ps, at, (vW, wW, aW, alW) = self._full_samples(mech)
        where = f"{self.where}.trajectory"
        std = standard_parametrisation(mech)
        if std is not None:  # closed form: the coordinates of the samples' platform poses
            pb, Rb = self.frame_to_platform(*at["0"])
            X0 = _standard_coordinates(mech, std, pb, Rb)

            def rates():  # X', X'' by the chain rule, computed when first read
                return _rates(ps, X0, self.coordinates_of(mech, *at["+"], where=where),
                              self.coordinates_of(mech, *at["-"], where=where))

            path = TaskPath(ps.t, X0, samples=ps, rates=rates)
        else:
            path = _chain(ps, self.coordinates_of(mech, *at["0"], where=where),
                          self.coordinates_of(mech, *at["+"], where=where),
                          self.coordinates_of(mech, *at["-"], where=where))
            Rb = self.frame_to_platform(*at["0"])[1] if self.frame == "tool" else None
        # the platform's twist and acceleration in B, exactly
        Rw = self.placement.R
        w, al, v, a = wW @ Rw.T, alW @ Rw.T, vW @ Rw.T, aW @ Rw.T
        if self.frame == "tool":  # from the tool point to the platform point
            d = -Rb @ np.array(self.tool.offset)
            v = v + _cross(w, d)
            a = a + _cross(al, d) + _cross(w, _cross(w, d))
        path.twist, path.accel = np.concatenate([v, w], axis=1), np.concatenate([a, al], axis=1)
        return path

    def _timed_path(self, mech, mode):
        tr = self.trajectory
        sub = Task(tr.values, coordinates=tr.coordinates, tool=self.tool, placement=self.placement,
                   convention=self.convention, frame=self.frame, where=f"{self.where}.trajectory.file")
        X = sub.platform_poses(mech)
        t = np.asarray(tr.times, dtype=float)
        Xd = np.gradient(X, t, axis=0, edge_order=2)
        Xdd = np.gradient(Xd, t, axis=0, edge_order=2)
        return TaskPath(t, X, Xd, Xdd, None)

    # -- reading a task file ---------------------------------------------------------------------------
    @classmethod
    def from_mapping(cls, mapping, *, units=None, base_dir=None, where: str = "task") -> "Task":
        """The task of a study's ``task:`` section (docs/tasks.md). Quantities carry their
        units (``"200 mm"``, ``"15 deg"``, ``"0.5 m/s"``); ``units`` ({kind: unit}, e.g.
        millimetres for lengths and degrees for angles) gives the unit of bare numbers and of CSV columns
        without one (a bare number without it is an error). Files are relative to
        ``base_dir`` (default the working directory). Raises :class:`TaskError` naming the key
        path under ``where``."""
        if isinstance(mapping, Mapping) and set(mapping) == {"file"}:
            return cls.from_file(mapping["file"], units=units, base_dir=base_dir, where=where)
        return _Reader(units, base_dir, where).task(mapping)

    @classmethod
    def from_file(cls, path, *, units=None, base_dir=None, where: str = "task") -> "Task":
        """The task of a task file (YAML: a ``task:`` mapping, or the mapping itself), e.g.
        ``studies/tasks/grinding_path.yaml``; a study names one with ``task: {file: ...}``. A
        relative ``path`` is read from ``base_dir`` (default the working directory), the files
        the task names from the task file's folder."""
        if not isinstance(path, (str, os.PathLike)) or not str(path):
            raise TaskError(f"{where}.file: give a task file name (YAML), got {path!r}")
        import yaml  # here: `import parasynth` loads no YAML parser (tests/test_layers.py)

        fn = os.fspath(path)
        if not os.path.isabs(fn) and base_dir is not None:
            fn = os.path.join(os.fspath(base_dir), fn)
        try:
            with open(fn, encoding="utf-8") as fh:
                data = yaml.safe_load(fh)
        except OSError as e:
            raise TaskError(f"{where}.file: cannot read {os.fspath(path)!r} ({e.strerror or e})") from None
        except yaml.YAMLError as e:
            raise TaskError(f"{where}.file: {os.fspath(path)!r} is not valid YAML ({str(e).splitlines()[0]})") from None
        if isinstance(data, Mapping) and set(data) == {"task"}:
            data = data["task"]
        if not isinstance(data, Mapping) or "file" in data and set(data) == {"file"}:
            raise TaskError(f"{where}.file: {os.fspath(path)!r} must hold a task mapping (poses, trajectory, ...)")
        return _Reader(units, os.path.dirname(os.path.abspath(fn)), where).task(data)


class TaskPath:
    """A task's path for one mechanism: ``t`` (K,) s, ``X``, ``Xd``, ``Xdd`` (K, d) its task
    coordinates and their time derivatives, ``samples`` the profile (None for timed poses);
    for a mechanism with six task coordinates also the platform's ``twist`` ``(v_P, omega)``
    and ``accel`` ``(a_P, alpha)`` (K, 6) in the base frame, from the profile exactly.

    ``rates``: instead of ``Xd`` and ``Xdd``, a function returning both, called when either is
    first read (the path of a mechanism with six task coordinates: its dynamics read the exact
    twist and acceleration, so the finite differences are computed only when asked for)."""

    def __init__(self, t, X, Xd=None, Xdd=None, samples: PathSamples | None = None, twist=None, accel=None,
                 rates=None):
        if rates is None and (Xd is None or Xdd is None):
            raise ValueError("TaskPath: give Xd and Xdd, or rates")
        self.t, self.X, self.samples, self.twist, self.accel = t, X, samples, twist, accel
        self._Xd, self._Xdd, self._rates = Xd, Xdd, rates

    def _get_rates(self):
        if self._Xd is None or self._Xdd is None:
            self._Xd, self._Xdd = self._rates()
            self._rates = None

    @property
    def Xd(self) -> np.ndarray:
        self._get_rates()
        return self._Xd

    @property
    def Xdd(self) -> np.ndarray:
        self._get_rates()
        return self._Xdd

    def __repr__(self) -> str:
        return f"<TaskPath {len(self.t)} samples, {self.X.shape[1]} coordinates>"


_STANDARD: dict = {}


def standard_parametrisation(mech):
    """``(convention, position columns, angle columns)`` when the mechanism's six task
    coordinates are its platform position and the angles of a named three-angle Euler
    convention (a description whose ``task:`` section says so, with no defined names); else
    None. Its coordinates of a pose are then the closed form, on the principal branch."""
    t = getattr(getattr(mech, "description", None), "task", None)
    key = (type(mech), id(t))
    hit = _STANDARD.get(key)
    if hit is not None and hit[0] is t:
        return hit[1]
    out = None
    tc = tuple(mech.task_coordinates)
    try:
        if t is not None and len(tc) == 6 and not t.defines and t.convention in TASK_CONVENTIONS:
            pos = [getattr(e, "text", None) for e in t.position]
            ang = [getattr(e, "text", None) for e in t.angles]
            if all(c in tc for c in pos + ang) and len(set(pos + ang)) == 6 \
                    and all(c in mech.angular_coordinates for c in ang):
                out = (t.convention, [tc.index(c) for c in pos], [tc.index(c) for c in ang])
    except (AttributeError, TypeError):
        out = None
    if len(_STANDARD) > 256:
        _STANDARD.clear()
    _STANDARD[key] = (t, out)
    return out


def _rmul(R, M):
    """``R @ M`` for a stack R (N, 3, 3) and one M (3, 3), as one matrix product."""
    return (R.reshape(-1, 3) @ M).reshape(R.shape)


def _lmul(M, R):
    """``M @ R`` for one M (3, 3) and a stack R (N, 3, 3), as one matrix product."""
    return np.swapaxes(_rmul(np.swapaxes(R, 1, 2), M.T), 1, 2)


#: Step of the progress for the derivatives of the mechanism's coordinates along a segment.
_H = 1e-4


def _rates(ps, X0, Xp, Xm):
    """X', X'' of the samples by the chain rule: central differences in the progress."""
    dXs = (Xp - Xm) / (2 * _H)
    d2Xs = (Xp - 2 * X0 + Xm) / (_H * _H)
    return dXs * ps.sd[:, None], d2Xs * (ps.sd ** 2)[:, None] + dXs * ps.sdd[:, None]


def _chain(ps, X0, Xp, Xm) -> "TaskPath":
    """The path with X, X', X'' of the samples by the chain rule (:func:`_rates`)."""
    Xd, Xdd = _rates(ps, X0, Xp, Xm)
    return TaskPath(ps.t, X0, Xd, Xdd, ps)


def _standard_coordinates(mech, std, pb, Rb) -> np.ndarray:
    """Task coordinates (N, 6) of platform poses ``(pb, Rb)`` in ``B`` for a mechanism whose
    coordinates are its position and named Euler angles (``std``, :func:`standard_parametrisation`)."""
    conv, ip, ia = std
    X = np.empty((pb.shape[0], mech.n_task))
    X[:, ip] = pb
    X[:, ia] = matrix_to_euler(conv, Rb)
    return X


def _read_only(arrays):
    """Mark an array (or each array of a tuple) read-only (values kept in a shared cache); returns it."""
    for a in (arrays if isinstance(arrays, tuple) else (arrays,)):
        a.setflags(write=False)
    return arrays


def _cross(a, b) -> np.ndarray:
    """Row-wise cross products (..., 3): the arithmetic of ``np.cross`` (the same results)
    without its per-call overhead."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.multiply(a1, b2, out=out[..., 0])
    out[..., 0] -= a2 * b1
    np.multiply(a2, b0, out=out[..., 1])
    out[..., 1] -= a0 * b2
    np.multiply(a0, b1, out=out[..., 2])
    out[..., 2] -= a1 * b0
    return out


def _standard_kind(name):
    return "length" if name in ("x", "y", "z") else ("angle" if name in _ANGLES else None)


def _angle_order(names, ang):
    if names:
        try:
            order = [getattr(a, "text", a) for a in names]
            if all(a in ang for a in order) and len(order) == 3:
                return order
        except TypeError:
            pass
    return ang


def _nearest_order(P: np.ndarray) -> np.ndarray:
    """Indices of the rows of ``P`` in greedy nearest-neighbour order from the first (NaN as 0)."""
    Q = np.nan_to_num(P)
    n = len(Q)
    left = np.ones(n, bool)
    order = [0]
    left[0] = False
    for _ in range(n - 1):
        d = np.linalg.norm(Q - Q[order[-1]], axis=1)
        d[~left] = np.inf
        k = int(np.argmin(d))
        order.append(k)
        left[k] = False
    return np.array(order, dtype=int)


def _check_floors(where, floors) -> dict:
    if not isinstance(floors, Mapping):
        raise TaskError(f"{where}: give a mapping {{condition: {{max: 500}}, ...}}, got {floors!r}")
    out = {}
    for k, v in floors.items():
        if k not in FLOOR_KINDS:
            raise TaskError(f"{where}.{k}: unknown floor; allowed: {', '.join(FLOOR_KINDS)}")
        bound = FLOOR_KINDS[k][0]
        if isinstance(v, Mapping):
            if set(v) != {bound}:
                raise TaskError(f"{where}.{k}: give {{{bound}: value}}, got {dict(v)!r}")
            v = v[bound]
        out[k] = _num(f"{where}.{k}.{bound}", v, "a number")
    return out


def solve_pose(mech, p, R, guess, where="task.poses", tol: float = 1e-6, max_iter: int = 40) -> np.ndarray:
    """Task coordinates (N, d) of ``mech`` whose platform pose is nearest ``(p, R)`` in ``B``:
    Gauss-Newton on the pose parametrisation from ``guess`` (lengths scaled by the length
    scale, halved steps where a full one does not improve), to the exact pose or the least
    squares one. :class:`TaskError` naming the first pose whose residual stays above ``tol``
    times the length scale (a pose outside the mechanism's freedoms; a mechanism whose
    orientation is coupled to its position reaches a shifted pose only to within such a
    residual)."""
    L = float(mech.length_scale)
    X = np.array(guess, dtype=float, copy=True)

    def err(Xc, sel=slice(None)):
        pc, Rc = mech.pose(Xc)
        return np.concatenate([(p[sel] - pc) / L, rotation_log(R[sel] @ np.swapaxes(Rc, 1, 2))], axis=1)

    e = err(X)
    n = np.linalg.norm(e, axis=1)
    active = ~(n <= 1e-12)
    it = 0
    lin = np.array([c not in mech.angular_coordinates for c in mech.task_coordinates])
    cs = np.where(lin, 1.0 / L, 1.0)
    while np.any(active) and it < max_iter:
        idx = np.flatnonzero(active)
        Ts = mech.twist_map(X[idx]) / cs[None, None, :]
        Ts[:, :3, :] /= L
        dY = np.einsum("nij,nj->ni", np.linalg.pinv(Ts, rcond=1e-10), e[idx])
        Xn = X[idx] + dY / cs
        en = err(Xn, idx)
        nn = np.linalg.norm(en, axis=1)
        better = nn < n[idx]
        if not np.all(better):  # a half step where the full one does not improve
            k = ~better
            Xh = X[idx[k]] + 0.5 * dY[k] / cs
            eh = err(Xh, idx[k])
            nh = np.linalg.norm(eh, axis=1)
            Xn[k], en[k], nn[k] = Xh, eh, nh
        take = nn <= n[idx]
        X[idx[take]], e[idx[take]], n[idx[take]] = Xn[take], en[take], nn[take]
        step = np.linalg.norm(dY, axis=1)
        active[idx] = take & (nn > 1e-12) & (step > 1e-13)
        it += 1
    bad = ~(n <= tol)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise TaskError(f"{where}[{i}]: the platform pose asked for is outside the freedoms of {mech.name} "
                        f"(residual {n[i]:.3g} of its length scale, above {tol:g}: a pose, placement or tool that "
                        f"needs a motion the mechanism does not have)")
    return X


# ---------------------------------------------------------------------------------------------
# the task file reader
# ---------------------------------------------------------------------------------------------
_KIND_DIM = {"speed": ("[length] / [time]", "m/s", "m/s"), "acceleration": ("[length] / [time] ** 2", "m/s^2", "m/s^2"),
             "angular_speed": ("1 / [time]", "rad/s", "deg/s"), "angular_acceleration": ("1 / [time] ** 2", "rad/s^2",
                                                                                          "deg/s^2"),
             "inertia": ("[mass] * [length] ** 2", "kg*m^2", "kg*m^2"), "gravity": ("[length] / [time] ** 2", "m/s^2",
                                                                                     "m/s^2"),
             "density": ("[mass] / [length] ** 3", "kg/m^3", "kg/m^3")}


class _Reader:
    def __init__(self, units, base_dir, where):
        if units is not None and not isinstance(units, Mapping):
            raise TaskError(f"units: give a mapping {{kind: unit}}, e.g. {{length: mm, angle: deg}}, got {units!r}")
        self.units = dict(units or {})
        for k, u in self.units.items():
            if k not in UNIT_KINDS or k == "dimensionless":
                raise TaskError(f"units.{k}: unknown kind; allowed: "
                                f"{', '.join(x for x in UNIT_KINDS if x != 'dimensionless')}")
            if not isinstance(u, str) or not u.strip():
                raise TaskError(f"units.{k}: give a unit such as 'mm', got {u!r}")
        self.base_dir = os.fspath(base_dir) if base_dir is not None else os.getcwd()
        self.where = where
        self.pose_kinds = {}

    def qpose(self, value, name, path):
        """A pose coordinate: x, y, z lengths, alpha, beta, gamma angles, other names (a
        mechanism's own coordinates) a length or an angle by their unit."""
        kind = _standard_kind(name)
        if kind is None:
            try:
                v, kind = self.q(value, "length", path), "length"
            except TaskError:
                try:
                    v, kind = self.q(value, "angle", path), "angle"
                except TaskError:
                    raise TaskError(f"{path}: give a length (e.g. '10 mm') or an angle (e.g. '5 deg'), "
                                    f"got {value!r}") from None
        else:
            v = self.q(value, kind, path)
        old = self.pose_kinds.setdefault(name, kind)
        if old != kind:
            raise TaskError(f"{path}: {name!r} is a{'n' if old == 'angle' else ''} {old} elsewhere, "
                            f"here a{'n' if kind == 'angle' else ''} {kind}")
        return v

    # quantities
    def q(self, value, kind, path):
        if isinstance(value, bool):
            raise TaskError(f"{path}: give a quantity with its unit, got {value!r}")
        if isinstance(value, (int, float)) and kind in self.units:
            value = f"{value} {self.units[kind]}"
        if kind in _KIND_DIM:
            return self._compound(value, kind, path)
        try:
            return parse_quantity(value, kind, field=path)
        except QuantityError as e:
            raise TaskError(str(e)) from None

    def _compound(self, value, kind, path):
        dim, si, example = _KIND_DIM[kind]
        if isinstance(value, (int, float)):
            raise TaskError(f"{path}: a bare number ({value!r}) is not allowed; give a unit, e.g. '{value} {example}'")
        if not isinstance(value, str) or len(value) > 200:
            raise TaskError(f"{path}: give a quantity such as '1 {example}', got {value!r}")
        try:
            q = _ureg().Quantity(value.strip())
        except Exception as e:  # pint raises several error types
            raise TaskError(f"{path}: cannot parse {value!r} ({e})") from None
        try:
            ok = q.check(dim) if kind not in ("angular_speed", "angular_acceleration") else \
                q.to(si).magnitude is not None
            v = float(q.to(si).magnitude) if ok else None
        except Exception:
            v = None
        if v is None or q.unitless:
            raise TaskError(f"{path}: {value!r} is not a {kind.replace('_', ' ')} (expected units like {example})")
        if not math.isfinite(v):
            raise TaskError(f"{path}: {value!r} is not finite")
        return v

    def qlist(self, value, kind, n, path):
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise TaskError(f"{path}: give a list of {n} values with units, got {value!r}")
        return tuple(self.q(v, kind, f"{path}[{j}]") for j, v in enumerate(value))

    def keys(self, m, allowed, path):
        if not isinstance(m, Mapping):
            raise TaskError(f"{path}: give a mapping with keys {', '.join(sorted(allowed))}, got {m!r}")
        for k in m:
            if k not in allowed:
                raise TaskError(f"{path}.{k}: unknown key; allowed: {', '.join(sorted(allowed))}")

    # the section
    def task(self, m):
        w = self.where
        self.keys(m, {"poses", "convention", "frame", "placement", "tool", "trajectory", "loads", "space", "floors",
                      "pose_tolerance", "doc"}, w)
        conv = m.get("convention", "xyz")
        if conv not in TASK_CONVENTIONS:
            raise TaskError(f"{w}.convention: unknown orientation convention {conv!r}; allowed: "
                            f"{', '.join(TASK_CONVENTIONS)}")
        if "poses" not in m:
            raise TaskError(f"{w}.poses: required (a grid, a list, a file, or several of them)")
        names, P, order = self.poses(m["poses"], f"{w}.poses")
        frame = m.get("frame", "tool")
        if frame not in ("tool", "platform"):
            raise TaskError(f"{w}.frame: must be tool or platform, got {frame!r}")
        placement = self.placement(m.get("placement"), f"{w}.placement")
        tool = self.tool(m.get("tool"), f"{w}.tool")
        loads = self.loads(m.get("loads"), f"{w}.loads", len(P))
        space, dia = self.space(m.get("space"), f"{w}.space")
        floors = _check_floors(f"{w}.floors", m.get("floors") or {})
        traj = self.trajectory(m.get("trajectory"), f"{w}.trajectory")
        try:
            return Task(P, coordinates=names, tool=tool, placement=placement, convention=conv, frame=frame,
                        trajectory=traj, space=space, floors=floors, order=order, leg_diameter=dia,
                        coordinate_kinds=dict(self.pose_kinds), where=w,
                        pose_tolerance=m.get("pose_tolerance", 1e-6), **loads)
        except TaskError as e:
            msg = str(e)
            raise TaskError(msg if msg.startswith(w) else f"{w}.{msg.removeprefix('task.')}") from None

    def poses(self, m, path):
        if isinstance(m, list):
            m = {"list": m}
        self.keys(m, {"grid", "list", "file", "order"}, path)
        parts = []
        if "grid" in m:
            parts.append(self.grid(m["grid"], f"{path}.grid"))
        if "list" in m:
            parts.append(self.plist(m["list"], f"{path}.list"))
        if "file" in m:
            parts.append(self.csv(m["file"], f"{path}.file"))
        if not parts:
            raise TaskError(f"{path}: give a grid, a list or a file of poses")
        names = []
        for nm, _ in parts:
            names += [c for c in nm if c not in names]
        rows = []
        for nm, V in parts:
            A = np.full((len(V), len(names)), np.nan)
            for j, c in enumerate(nm):
                A[:, names.index(c)] = V[:, j]
            rows.append(A)
        order = m.get("order", "given")
        if order not in ("given", "nearest"):
            raise TaskError(f"{path}.order: must be given or nearest, got {order!r}")
        P = np.concatenate(rows, axis=0)
        if len(P) > 10_000_000:
            raise TaskError(f"{path}: {len(P)} poses are too many (at most 10,000,000)")
        return tuple(names), P, order

    def grid(self, g, path):
        if not isinstance(g, Mapping) or not g:
            raise TaskError(f"{path}: give {{coordinate: [low, high, step] or {{values: [...]}}}}, got {g!r}")
        axes, names = [], []
        for c, spec in g.items():
            p = f"{path}.{c}"
            if isinstance(spec, Mapping):
                self.keys(spec, {"values", "low", "high", "step"}, p)
                if "values" in spec:
                    if set(spec) != {"values"}:
                        raise TaskError(f"{p}: give either values or low, high and step")
                    vals = spec["values"]
                    if not isinstance(vals, list) or not vals:
                        raise TaskError(f"{p}.values: give a non-empty list of values with units")
                    axes.append(np.array([self.qpose(v, c, f"{p}.values[{j}]") for j, v in enumerate(vals)]))
                    names.append(c)
                    continue
                missing = [k for k in ("low", "high", "step") if k not in spec]
                if missing:
                    raise TaskError(f"{p}.{missing[0]}: required (give low, high and step)")
                spec = [spec["low"], spec["high"], spec["step"]]
            if not isinstance(spec, (list, tuple)) or len(spec) != 3:
                raise TaskError(f"{p}: give [low, high, step] with units or {{values: [...]}}, got {spec!r}")
            lo, hi, st = (self.qpose(v, c, f"{p}[{j}]") for j, v in enumerate(spec))
            if st <= 0:
                raise TaskError(f"{p}[2]: the step must be positive, got {spec[2]!r}")
            if hi < lo:
                raise TaskError(f"{p}: high {spec[1]!r} is below low {spec[0]!r}")
            n = int(math.floor((hi - lo) / st + 1e-9)) + 1
            if n > 100_000:
                raise TaskError(f"{p}: {n} values are too many (at most 100,000 per axis)")
            axes.append(lo + st * np.arange(n))
            names.append(c)
        mesh = np.meshgrid(*axes, indexing="ij")
        return names, np.stack([a.ravel() for a in mesh], axis=1)

    def plist(self, lst, path):
        if not isinstance(lst, list) or not lst:
            raise TaskError(f"{path}: give a non-empty list of poses {{coordinate: value}}")
        names = []
        for i, pose in enumerate(lst):
            if not isinstance(pose, Mapping) or not pose:
                raise TaskError(f"{path}[{i}]: give a pose {{coordinate: value with unit}}, got {pose!r}")
            names += [c for c in pose if c not in names]
        V = np.full((len(lst), len(names)), np.nan)
        for i, pose in enumerate(lst):
            for c, v in pose.items():
                V[i, names.index(c)] = self.qpose(v, c, f"{path}[{i}].{c}")
        return names, V

    def _read_csv(self, f, path, need_time=False, kind_of=None):
        if not isinstance(f, str) or not f:
            raise TaskError(f"{path}: give a file name (relative to the study file), got {f!r}")
        fn = f if os.path.isabs(f) else os.path.join(self.base_dir, f)
        try:
            with open(fn, newline="") as fh:
                rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
        except OSError as e:
            raise TaskError(f"{path}: cannot read {f!r} ({e.strerror or e})") from None
        if len(rows) < 2:
            raise TaskError(f"{path}: {f!r} needs a header of named columns and at least one row")
        header = [h.strip() for h in rows[0]]
        cols = []
        for j, h in enumerate(header):
            name, unit = h, None
            if "[" in h and h.endswith("]"):
                name, unit = h[:h.index("[")].strip(), h[h.index("[") + 1:-1].strip()
            if not name.isidentifier():
                raise TaskError(f"{path}: {f!r} column {j + 1} has no name (header {h!r}); name it, e.g. 'x [mm]'")
            cols.append((name, unit))
        names = [c for c, _ in cols]
        dup = sorted({c for c in names if names.count(c) > 1})
        if dup:
            raise TaskError(f"{path}: {f!r} has column {dup[0]!r} twice")
        data = np.full((len(rows) - 1, len(cols)), np.nan)
        for i, r in enumerate(rows[1:]):
            if len(r) != len(cols):
                raise TaskError(f"{path}: {f!r} row {i + 2} has {len(r)} values for {len(cols)} columns")
            for j, (c, unit) in enumerate(cols):
                kind = "time" if c == "t" else (kind_of(c) if kind_of else _standard_kind(c))
                txt = r[j].strip()
                try:
                    v = float(txt)
                except ValueError:
                    raise TaskError(f"{path}: {f!r} row {i + 2} column {c!r}: {txt!r} is not a number") from None
                if not math.isfinite(v):
                    raise TaskError(f"{path}: {f!r} row {i + 2} column {c!r}: {txt!r} is not finite")
                if unit is None:
                    if kind not in self.units:
                        raise TaskError(f"{path}: {f!r} column {c!r} has no unit; write it in the header, e.g. "
                                        f"'{c} [{'s' if kind == 'time' else ('deg' if kind == 'angle' else 'mm')}]'")
                    unit = self.units[kind]
                    cols[j] = (c, unit)
                where_c = f"{path} column {c!r}"
                if kind is None:
                    data[i, j] = self.qpose(f"{v!r} {unit}", c, where_c)
                else:
                    data[i, j] = self.q(f"{v!r} {unit}", kind, where_c)
                    if kind in ("length", "angle"):
                        self.pose_kinds.setdefault(c, kind)
        if need_time:
            if "t" not in names:
                raise TaskError(f"{path}: {f!r} has no time column 't [s]'")
            k = names.index("t")
            t = data[:, k]
            rest = [c for c in names if c != "t"]
            return rest, np.delete(data, k, axis=1), t
        return names, data

    def csv(self, f, path):
        names, data = self._read_csv(f, path)
        if "t" in names:  # a file of timed poses: the poses without their times
            k = names.index("t")
            names, data = [c for c in names if c != "t"], np.delete(data, k, axis=1)
        return names, data

    def placement(self, m, path):
        if m is None:
            return Placement()
        self.keys(m, {"x", "y", "z", "yaw", "hanging"}, path)
        off = tuple(self.q(m[k], "length", f"{path}.{k}") if k in m else 0.0 for k in "xyz")
        yaw = self.q(m["yaw"], "angle", f"{path}.yaw") if "yaw" in m else 0.0
        hanging = m.get("hanging", False)
        if not isinstance(hanging, bool):
            raise TaskError(f"{path}.hanging: give true or false, got {hanging!r}")
        return Placement(off, yaw, hanging)

    def tool(self, m, path):
        if m is None:
            return Tool()
        self.keys(m, {"x", "y", "z", "yaw"}, path)
        off = tuple(self.q(m[k], "length", f"{path}.{k}") if k in m else 0.0 for k in "xyz")
        yaw = self.q(m["yaw"], "angle", f"{path}.yaw") if "yaw" in m else 0.0
        return Tool(off, yaw)

    def loads(self, m, path, n_poses):
        if m is None:
            return {}
        self.keys(m, {"payload", "wrench", "signs", "frame", "gravity", "leg_density"}, path)
        out = {}
        if "leg_density" in m:
            rho = self.q(m["leg_density"], "density", f"{path}.leg_density")
            if rho < 0:
                raise TaskError(f"{path}.leg_density: must be >= 0, got {m['leg_density']!r}")
            out["leg_density"] = rho
        if "payload" in m:
            pl = m["payload"]
            self.keys(pl, {"mass", "com", "inertia"}, f"{path}.payload")
            mass = self.q(pl.get("mass", "0 kg"), "mass", f"{path}.payload.mass")
            com = self.qlist(pl["com"], "length", 3, f"{path}.payload.com") if "com" in pl else (0.0, 0.0, 0.0)
            inertia = (0.0, 0.0, 0.0)
            if "inertia" in pl:
                I = pl["inertia"]
                if isinstance(I, list) and len(I) == 3 and all(isinstance(r, list) for r in I):
                    inertia = tuple(self.qlist(r, "inertia", 3, f"{path}.payload.inertia[{i}]")
                                    for i, r in enumerate(I))
                else:
                    inertia = self.qlist(I, "inertia", 3, f"{path}.payload.inertia")
            try:
                out["payload"] = Payload(mass, com, inertia)
            except TaskError as e:
                raise TaskError(f"{path}.{e}") from None
        if "wrench" in m:
            wr = m["wrench"]
            if isinstance(wr, Mapping) and "file" in wr:
                self.keys(wr, {"file"}, f"{path}.wrench")
                names, data = self._wrench_csv(wr["file"], f"{path}.wrench.file")
                if len(data) != n_poses:
                    raise TaskError(f"{path}.wrench.file: {len(data)} rows for {n_poses} poses")
                out["wrench"] = data
            elif isinstance(wr, list) and wr and all(isinstance(r, (list, Mapping)) for r in wr):
                if len(wr) != n_poses:
                    raise TaskError(f"{path}.wrench: {len(wr)} wrenches for {n_poses} poses (one per pose, or one)")
                out["wrench"] = np.array([self._wrench(r, f"{path}.wrench[{i}]") for i, r in enumerate(wr)])
            else:
                out["wrench"] = self._wrench(wr, f"{path}.wrench")
        if "signs" in m:
            if not isinstance(m["signs"], bool):
                raise TaskError(f"{path}.signs: give true or false, got {m['signs']!r}")
            out["wrench_signs"] = m["signs"]
        if "frame" in m:
            if m["frame"] not in ("task", "base", "tool"):
                raise TaskError(f"{path}.frame: must be task, base or tool, got {m['frame']!r}")
            out["wrench_frame"] = m["frame"]
        if "gravity" in m:
            if isinstance(m["gravity"], list):
                out["gravity"] = self.qlist(m["gravity"], "gravity", 3, f"{path}.gravity")
            else:
                g = self.q(m["gravity"], "gravity", f"{path}.gravity")
                if g < 0:
                    raise TaskError(f"{path}.gravity: must be >= 0, got {m['gravity']!r}")
                out["gravity"] = g
        return out

    def _wrench(self, wr, path):
        if isinstance(wr, Mapping):
            self.keys(wr, {"force", "moment"}, path)
            f = self.qlist(wr.get("force", ["0 N"] * 3), "force", 3, f"{path}.force")
            mo = self.qlist(wr.get("moment", ["0 N*m"] * 3), "torque", 3, f"{path}.moment")
            return np.array(f + mo)
        if not isinstance(wr, list) or len(wr) != 6:
            raise TaskError(f"{path}: give [fx, fy, fz, mx, my, mz] with units (N, N*m) or {{force, moment}}, "
                            f"got {wr!r}")
        return np.array([self.q(v, "force" if j < 3 else "torque", f"{path}[{j}]") for j, v in enumerate(wr)])

    def _wrench_csv(self, f, path):
        names, data = self._read_csv_kinds(f, path)
        return names, data

    def _read_csv_kinds(self, f, path):
        # wrench columns: fx fy fz [N], mx my mz [N*m]
        want = ("fx", "fy", "fz", "mx", "my", "mz")
        names, data = self._read_csv(f, path, kind_of=lambda c: "force" if c in want[:3] else
                                     ("torque" if c in want[3:] else "dimensionless"))
        missing = [c for c in want if c not in names]
        if missing:
            raise TaskError(f"{path}: {f!r} has no column {missing[0]!r} (columns fx, fy, fz [N], mx, my, mz [N*m])")
        return want, data[:, [names.index(c) for c in want]]

    def space(self, m, path):
        if m is None:
            return None, None
        self.keys(m, {"box", "cylinder", "base_plane", "leg_diameter"}, path)
        if ("box" in m) == ("cylinder" in m):
            raise TaskError(f"{path}: give one of box or cylinder")
        bp = m.get("base_plane", True)
        if not isinstance(bp, bool):
            raise TaskError(f"{path}.base_plane: give true (moving parts may pass the base plane) or false, got {bp!r}")
        dia = self.q(m["leg_diameter"], "length", f"{path}.leg_diameter") if "leg_diameter" in m else None
        try:
            if "box" in m:
                b = m["box"]
                self.keys(b, {"low", "high"}, f"{path}.box")
                for k in ("low", "high"):
                    if k not in b:
                        raise TaskError(f"{path}.box.{k}: required ([x, y, z] with units)")
                return Space("box", low=self.qlist(b["low"], "length", 3, f"{path}.box.low"),
                             high=self.qlist(b["high"], "length", 3, f"{path}.box.high"), base_plane=bp), dia
            c = m["cylinder"]
            self.keys(c, {"radius", "z", "center"}, f"{path}.cylinder")
            for k in ("radius", "z"):
                if k not in c:
                    raise TaskError(f"{path}.cylinder.{k}: required")
            return Space("cylinder", radius=self.q(c["radius"], "length", f"{path}.cylinder.radius"),
                         z=self.qlist(c["z"], "length", 2, f"{path}.cylinder.z"),
                         center=self.qlist(c.get("center", ["0 m", "0 m"]), "length", 2, f"{path}.cylinder.center"),
                         base_plane=bp), dia
        except TaskError as e:
            msg = str(e)
            raise TaskError(msg if msg.startswith(path) else f"{path}.{msg.removeprefix('space.')}") from None

    def trajectory(self, m, path):
        if m is None:
            return None
        self.keys(m, {"speed", "acceleration", "angular_speed", "angular_acceleration", "jerk_time", "dt", "file",
                      "limits", "timing", "waypoints"}, path)
        if "file" in m:
            if set(m) != {"file"}:
                raise TaskError(f"{path}: a file of timed poses takes no motion limits")
            names, data, t = self._read_csv(m["file"], f"{path}.file", need_time=True)
            try:
                return TrajectorySpec(times=t, values=data, coordinates=tuple(names))
            except TaskError as e:
                raise TaskError(f"{path}.file: {str(e).split(': ', 1)[-1]}") from None
        for k in ("speed", "acceleration"):
            if k not in m and not (k == "speed" and "angular_speed" in m) and \
                    not (k == "acceleration" and "angular_acceleration" in m):
                raise TaskError(f"{path}.{k}: required (with its unit)")
        kw = {}
        for k in ("speed", "acceleration", "angular_speed", "angular_acceleration"):
            if k in m:
                v = self.q(m[k], k, f"{path}.{k}")
                if not v > 0:
                    raise TaskError(f"{path}.{k}: must be positive, got {m[k]!r}")
                kw[k] = v
        kw.setdefault("speed", np.inf)
        kw.setdefault("acceleration", np.inf)
        if "jerk_time" in m:
            jt = self.q(m["jerk_time"], "time", f"{path}.jerk_time")
            if jt < 0:
                raise TaskError(f"{path}.jerk_time: must be >= 0, got {m['jerk_time']!r}")
            kw["jerk_time"] = jt
        dt = self.q(m["dt"], "time", f"{path}.dt") if "dt" in m else 0.01
        if not dt > 0:
            raise TaskError(f"{path}.dt: must be positive, got {m.get('dt')!r}")
        for k, allowed in (("limits", LIMIT_MODES), ("timing", TIMINGS)):
            if k in m:
                if m[k] not in allowed:
                    raise TaskError(f"{path}.{k}: must be one of {', '.join(allowed)}, got {m[k]!r}")
                kw[k] = m[k]
        if kw.get("timing") == "sampled":
            kw["step"] = dt
        try:
            lim = MotionLimits(**kw)
        except ValueError as e:
            raise TaskError(f"{path}.{e}") from None
        if "waypoints" in m:
            wp = m["waypoints"]
            if isinstance(wp, Mapping) and "order" in wp:
                raise TaskError(f"{path}.waypoints.order: the path runs through its waypoints in the given order")
            names, P, _ = self.poses(wp, f"{path}.waypoints")
            if len(P) < 2:
                raise TaskError(f"{path}.waypoints: give at least 2 poses")
            return TrajectorySpec(lim, dt, waypoints=P, waypoint_coordinates=tuple(names))
        return TrajectorySpec(lim, dt)
