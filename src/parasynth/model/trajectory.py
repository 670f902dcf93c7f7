"""Point-to-point motion profiles of trapezoidal acceleration (jerk-limited), sampled in time.

A task's path visits its required poses in order, stopping at each: every segment from one pose
to the next is followed along a straight line in the path's coordinates (positions; rotations
about one fixed axis, see :mod:`parasynth.model.task`) with a normalised progress ``s(t)`` from
0 to 1. The progress has a **trapezoidal acceleration**: the acceleration ramps linearly from 0
to its peak in the jerk ramp time ``t_j``, holds, and ramps back to 0; the speed then cruises
and the mirror image brings the motion to rest (the classic seven-phase "S-curve"). Where the
segment is too short to reach the speed limit (or the acceleration limit) the peak speed (and
peak acceleration) is lowered so that the segment is exactly covered; the jerk ramp time stays
``t_j`` unless the peak acceleration is not reached, then the jerk stays ``a_max / t_j`` and the
ramps are shorter.

Translational and rotational limits are separate: a segment of translation ``D`` (m) and
rotation ``Theta`` (rad) is timed on the progress ``s`` with speed limit
``min(v_t / D, v_r / Theta)`` and acceleration limit ``min(a_t / D, a_r / Theta)`` (per unit
of progress), so both motions start and stop together and each stays within its limits. The
jerk ramp time is common to both.

Everything is vectorised over segments and samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MotionLimits", "SegmentTiming", "PathSamples", "segment_timing", "sample_path", "profile_at"]


@dataclass(frozen=True)
class MotionLimits:
    """Limits of a point-to-point motion, SI: ``speed`` (m/s) and ``acceleration`` (m/s^2) of
    the translation, ``angular_speed`` (rad/s) and ``angular_acceleration`` (rad/s^2) of the
    rotation, and the ``jerk_time`` (s, >= 0) over which the acceleration ramps up or down
    (0: a trapezoidal speed profile of unbounded jerk). Limits must be positive; ``inf``
    leaves a motion unlimited (at least one of each pair must be finite where it moves)."""

    speed: float
    acceleration: float
    angular_speed: float = np.inf
    angular_acceleration: float = np.inf
    jerk_time: float = 0.0

    def __post_init__(self):
        for name in ("speed", "acceleration", "angular_speed", "angular_acceleration"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise ValueError(f"{name}: must be a positive number (SI), got {v!r}")
            if not (float(v) > 0) or np.isnan(v):
                raise ValueError(f"{name}: must be positive (SI), got {v!r}")
            object.__setattr__(self, name, float(v))
        j = self.jerk_time
        if isinstance(j, bool) or not isinstance(j, (int, float, np.floating, np.integer)) or not np.isfinite(j) \
                or j < 0:
            raise ValueError(f"jerk_time: must be a finite time >= 0 (s), got {j!r}")
        object.__setattr__(self, "jerk_time", float(j))


@dataclass(frozen=True)
class SegmentTiming:
    """Timing of M segments on their normalised progress: ``v`` peak progress rate (1/s),
    ``a`` peak progress acceleration (1/s^2), ``tj`` the ramp time actually used (s), ``ta``
    the acceleration (= deceleration) phase (s), ``tc`` the cruise (s), ``duration`` (s),
    ``start`` (s) of each segment on the path."""

    v: np.ndarray
    a: np.ndarray
    tj: np.ndarray
    ta: np.ndarray
    tc: np.ndarray
    duration: np.ndarray
    start: np.ndarray

    @property
    def total(self) -> float:
        return float(self.start[-1] + self.duration[-1]) if len(self.start) else 0.0


def segment_timing(distance, angle, limits: MotionLimits) -> SegmentTiming:
    """Timing of segments of translation ``distance`` (M,) m and rotation ``angle`` (M,) rad
    (zero-length segments take no time) under ``limits``."""
    D = np.asarray(distance, dtype=float).reshape(-1)
    A = np.asarray(angle, dtype=float).reshape(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        vlim = np.minimum(np.where(D > 0, limits.speed / D, np.inf), np.where(A > 0, limits.angular_speed / A, np.inf))
        alim = np.minimum(np.where(D > 0, limits.acceleration / D, np.inf),
                          np.where(A > 0, limits.angular_acceleration / A, np.inf))
    moving = (D > 0) | (A > 0)
    if np.any(moving & ~(np.isfinite(vlim) & np.isfinite(alim))):
        raise ValueError("a segment moves without a finite speed and acceleration limit for its motion "
                         "(give the translational or rotational limits)")
    vlim = np.where(moving, vlim, 1.0)
    alim = np.where(moving, alim, 1.0)
    tj = np.full(D.shape, limits.jerk_time)
    # Distance (progress) covered by an acceleration from rest to v and back: v * ta(v), with
    # ta(v) = v / a + tj when the peak acceleration a is reached (v >= a tj), else
    # 2 sqrt(v tj / a) (the jerk a / tj throughout).
    full = vlim >= alim * tj
    ta_full = np.where(full, vlim / alim + tj, 2.0 * np.sqrt(vlim * tj / alim))
    reach = vlim * ta_full <= 1.0
    # The speed limit is not reached on a unit progress: peak speed v with v ta(v) = 1.
    v1 = 0.5 * alim * (-tj + np.sqrt(tj * tj + 4.0 / alim))  # peak acceleration reached
    with np.errstate(divide="ignore", invalid="ignore"):
        v2 = np.where(tj > 0, (1.0 / (2.0 * np.sqrt(tj / alim))) ** (2.0 / 3.0), v1)  # jerk-limited throughout
    v_short = np.where(v1 >= alim * tj, v1, v2)
    v = np.where(reach, vlim, v_short)
    a_full = v >= alim * tj
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(a_full, alim, np.sqrt(v * alim / np.where(tj > 0, tj, 1.0)))
        tj_used = np.where(a_full, tj, np.sqrt(v * tj / alim))
    ta = np.where(a_full, v / alim + tj, 2.0 * tj_used)
    tc = np.where(reach, (1.0 - v * ta) / v, 0.0)
    tc = np.maximum(tc, 0.0)
    dur = np.where(moving, 2.0 * ta + tc, 0.0)
    v = np.where(moving, v, 0.0)
    a = np.where(moving, a, 0.0)
    start = np.concatenate([[0.0], np.cumsum(dur)[:-1]]) if len(dur) else np.zeros(0)
    return SegmentTiming(v, a, np.where(moving, tj_used, 0.0), np.where(moving, ta, 0.0), tc, dur, start)


def _accel_phase(tau, v, a, tj, ta):
    """Progress, rate, acceleration and jerk during the acceleration phase at times ``tau``
    in [0, ta] (arrays of equal shape), using its point symmetry about ta / 2."""
    second = tau > 0.5 * ta
    sg = np.where(second, ta - tau, tau)  # in [0, ta / 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        j = np.where(tj > 0, a / np.where(tj > 0, tj, 1.0), 0.0)
    ramp = (sg < tj) & (tj > 0)
    # ramp: a = j s, v = j s^2 / 2, x = j s^3 / 6; then constant a from (tj, v1 = a tj / 2, x1 = a tj^2 / 6)
    u = sg - tj
    x_d = np.where(ramp, j * sg ** 3 / 6.0, a * tj * tj / 6.0 + 0.5 * a * tj * u + 0.5 * a * u * u)
    v_d = np.where(ramp, 0.5 * j * sg * sg, 0.5 * a * tj + a * u)
    a_d = np.where(ramp, j * sg, a)
    jk_d = np.where(ramp, j, 0.0)
    X_A = 0.5 * v * ta
    x = np.where(second, X_A - (v * sg - x_d), x_d)
    vel = np.where(second, v - v_d, v_d)
    acc = a_d
    jerk = np.where(second, -jk_d, jk_d)
    return x, vel, acc, jerk


def profile_at(t, timing: SegmentTiming, segment) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Progress ``s``, rate, acceleration and jerk (1, 1/s, 1/s^2, 1/s^3) at times ``t`` from
    the start of each sample's ``segment``."""
    seg = np.asarray(segment, dtype=int)
    t = np.asarray(t, dtype=float)
    v, a, tj, ta, tc, dur = (getattr(timing, k)[seg] for k in ("v", "a", "tj", "ta", "tc", "duration"))
    t = np.clip(t, 0.0, dur)
    acc_ph = t <= ta
    dec_ph = t >= ta + tc
    xa, va, aa, ja = _accel_phase(np.minimum(t, ta), v, a, tj, ta)
    sd_ = np.clip(dur - t, 0.0, ta)
    xd, vd, ad, jd = _accel_phase(sd_, v, a, tj, ta)
    X_A = 0.5 * v * ta
    s = np.where(acc_ph, xa, np.where(dec_ph, 1.0 - xd, X_A + v * (t - ta)))
    sd = np.where(acc_ph, va, np.where(dec_ph, vd, v))
    sdd = np.where(acc_ph, aa, np.where(dec_ph, -ad, 0.0))
    sddd = np.where(acc_ph, ja, np.where(dec_ph, jd, 0.0))
    still = dur <= 0
    s = np.where(still, 1.0, s)
    return s, np.where(still, 0.0, sd), np.where(still, 0.0, sdd), np.where(still, 0.0, sddd)


@dataclass(frozen=True)
class PathSamples:
    """A path sampled in time: ``t`` (K,) s, ``segment`` (K,) the segment each sample lies on,
    ``s``, ``sd``, ``sdd``, ``sddd`` (K,) its progress and derivatives, ``timing``."""

    t: np.ndarray
    segment: np.ndarray
    s: np.ndarray
    sd: np.ndarray
    sdd: np.ndarray
    sddd: np.ndarray
    timing: SegmentTiming


def sample_path(distance, angle, limits: MotionLimits, dt: float, max_samples: int = 10_000_000) -> PathSamples:
    """The path of segments (``distance`` m, ``angle`` rad each) sampled every ``dt`` seconds
    from 0 to its end (the end included). A sample at a segment boundary belongs to the
    segment that starts there (at rest, progress 0), the last one to the last segment."""
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating)) or not np.isfinite(dt) or dt <= 0:
        raise ValueError(f"dt must be a positive time step (s), got {dt!r}")
    timing = segment_timing(distance, angle, limits)
    T = timing.total
    n = int(np.floor(T / dt + 1e-9)) + 1
    if n > max_samples:
        raise ValueError(f"the path takes {T:.4g} s: {n} samples at dt = {dt} s exceed {max_samples}; "
                         f"give a larger time step")
    t = np.arange(n) * float(dt)
    if T - t[-1] > 1e-12 * max(T, 1.0):
        t = np.append(t, T)
    M = len(timing.duration)
    if M == 0:
        z = np.zeros(len(t))
        return PathSamples(t, np.zeros(len(t), int), z + 1.0, z, z, z, timing)
    seg = np.searchsorted(timing.start, t, side="right") - 1
    seg = np.clip(seg, 0, M - 1)
    # skip zero-length segments: a sample on one belongs to the next moving one (or the last)
    s, sd, sdd, sddd = profile_at(t - timing.start[seg], timing, seg)
    return PathSamples(t, seg, s, sd, sdd, sddd, timing)
