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

Two options follow the dimensional-synthesis toolbox of Schappler et al. (the profile
``traj_trapez2_multipoint`` of SchapplM/robotics-dep-traj, which calls Lambrechts' ``make3``):

* ``limits``: ``"path"`` (the default, above: the limits bound the Euclidean norm of the
  translation's speed and acceleration and the rotation's angular speed and acceleration along
  the segment) or ``"per_coordinate"``: they bound each coordinate separately. The caller then
  passes per segment the largest change of a single translational coordinate as ``distance``
  and of a single angular coordinate as ``angle`` (the infinity norms); the coordinate that
  needs the longest time sets the segment's profile and every other coordinate follows it,
  scaled (a straight line in the coordinates, as ``traj_trapezN`` synchronises its axes to the
  slowest one).
* ``timing``: ``"continuous"`` (the default: phase durations exact) or ``"sampled"``: each phase
  duration (jerk ramp ``t1``, constant acceleration ``t2``, cruise ``t3``) is rounded **up** to a
  whole number of ``step`` seconds and the jerk lowered so that the segment is covered exactly
  (``make3`` of Lambrechts, "Trajectory planning and feedforward design for electromechanical
  motion systems", 2003, with its sample time), and the segments follow each other with a pause
  of one ``step`` at rest (``traj_trapez2_multipoint`` with ``T_pause = 0``: every corner is
  sampled twice, one step apart). A segment that does not move lasts one ``step``. Rounding up
  lowers the peak speed and acceleration of short segments (a 100 mm segment at 1 m/s, 3 m/s^2,
  0.1 s jerk ramp and 50 ms steps peaks at 0.333 m/s instead of 0.410 m/s).

Everything is vectorised over segments and samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MotionLimits", "SegmentTiming", "PathSamples", "segment_timing", "sample_path", "profile_at",
           "LIMIT_MODES", "TIMINGS"]

#: How the limits apply: to the path's speed (norms) or to each coordinate.
LIMIT_MODES = ("path", "per_coordinate")
#: Phase durations: exact, or rounded up to whole time steps.
TIMINGS = ("continuous", "sampled")


@dataclass(frozen=True)
class MotionLimits:
    """Limits of a point-to-point motion, SI: ``speed`` (m/s) and ``acceleration`` (m/s^2) of
    the translation, ``angular_speed`` (rad/s) and ``angular_acceleration`` (rad/s^2) of the
    rotation, and the ``jerk_time`` (s, >= 0) over which the acceleration ramps up or down
    (0: a trapezoidal speed profile of unbounded jerk). Limits must be positive; ``inf``
    leaves a motion unlimited (at least one of each pair must be finite where it moves).
    ``limits``: ``"path"`` or ``"per_coordinate"``, ``timing``: ``"continuous"`` or ``"sampled"``
    with its rounding ``step`` (s; see the module documentation)."""

    speed: float
    acceleration: float
    angular_speed: float = np.inf
    angular_acceleration: float = np.inf
    jerk_time: float = 0.0
    limits: str = "path"
    timing: str = "continuous"
    step: float | None = None

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
        if self.limits not in LIMIT_MODES:
            raise ValueError(f"limits: must be one of {', '.join(LIMIT_MODES)}, got {self.limits!r}")
        if self.timing not in TIMINGS:
            raise ValueError(f"timing: must be one of {', '.join(TIMINGS)}, got {self.timing!r}")
        if self.timing == "sampled":
            st = self.step
            if isinstance(st, bool) or not isinstance(st, (int, float, np.floating, np.integer)) \
                    or not np.isfinite(st) or st <= 0:
                raise ValueError(f"step: sampled timing rounds phases to a time step > 0 (s), got {st!r}")
            object.__setattr__(self, "step", float(st))
            if not self.jerk_time > 0:
                raise ValueError("jerk_time: sampled timing needs a jerk ramp time > 0 (s)")
        elif self.step is not None:
            raise ValueError("step: only sampled timing takes a rounding step")


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
    moving: np.ndarray | None = None

    @property
    def total(self) -> float:
        return float(self.start[-1] + self.duration[-1]) if len(self.start) else 0.0


def _make3(p, v, a, j, Ts):
    """Phase durations ``t1`` (jerk), ``t2`` (constant acceleration), ``t3`` (cruise) and the
    lowered jerk of symmetric third-order profiles over distances ``p`` (> 0) under the bounds
    ``v``, ``a``, ``j`` with every phase a whole number of steps ``Ts`` (rounded up):
    Lambrechts' ``make3`` (2003) step by step, vectorised (the same arithmetic in the same
    order, so that the same roundings occur)."""
    eps = np.finfo(float).eps
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t1 = (p / (2 * j)) ** (1 / 3)
        t1 = np.ceil(t1 / Ts) * Ts
        jd = 1 / 2 * p / (t1 ** 3)
        c = v < jd * t1 ** 2
        t1c = np.ceil((v / j) ** (1 / 2) / Ts) * Ts
        t1, jd = np.where(c, t1c, t1), np.where(c, v / (t1c ** 2), jd)
        c = a < jd * t1
        t1c = np.ceil((a / j) / Ts) * Ts
        t1, jd = np.where(c, t1c, t1), np.where(c, a / t1c, jd)
        j = jd
        t2 = (t1 ** 2 / 4 + p / j / t1) ** (1 / 2) - 3 / 2 * t1
        t2 = np.ceil(t2 / Ts) * Ts
        jd = p / (2 * t1 ** 3 + 3 * t1 ** 2 * t2 + t1 * t2 ** 2)
        t2 = np.where(np.abs(t2) < eps, 0.0, t2)
        c = v < (jd * t1 ** 2 + jd * t1 * t2)
        t2c = np.ceil((v / (j * t1) - t1) / Ts) * Ts
        t2, jd = np.where(c, t2c, t2), np.where(c, v / (t1 ** 2 + t1 * t2c), jd)
        t2 = np.where(np.abs(t2) < eps, 0.0, t2)
        j = jd
        t3 = (p - 2 * j * t1 ** 3 - 3 * j * t1 ** 2 * t2 - j * t1 * t2 ** 2) / v
        t3 = np.ceil(t3 / Ts) * Ts
        jd = p / (2 * t1 ** 3 + 3 * t1 ** 2 * t2 + t1 * t2 ** 2 + t1 ** 2 * t3 + t1 * t2 * t3)
        t3 = np.where(np.abs(t3) < eps, 0.0, t3)
    return t1, t2, t3, jd


def _sampled_timing(D, A, limits: MotionLimits) -> SegmentTiming:
    """:func:`segment_timing` with phases rounded up to whole steps (``timing="sampled"``):
    each motion (translation ``D``, rotation ``A``) is profiled with its own limits as the
    toolbox profiles each axis (speed ``v``, ramp time of the speed ``v / a``, jerk ``v / (T2
    tj)``), the slower sets the segment's progress."""
    Ts = limits.step
    moving = (D > 0) | (A > 0)
    best = None
    for dist, v, a in ((D, limits.speed, limits.acceleration), (A, limits.angular_speed,
                                                                  limits.angular_acceleration)):
        on = dist > 0
        if not np.any(on):
            continue
        if not (np.isfinite(v) and np.isfinite(a)):
            raise ValueError("sampled timing needs finite speed and acceleration limits for every motion of the path "
                             "(give the translational and rotational limits)")
        T2 = v / a
        p = np.where(on, dist, 1.0)
        t1, t2, t3, jd = _make3(p, v, v / T2, v / (T2 * limits.jerk_time), Ts)
        dur = np.where(on, 4 * t1 + 2 * t2 + t3, 0.0)
        cand = (dur, t1, t2, t3, jd / p)  # the jerk per unit of progress
        if best is None:
            best = cand
        else:
            take = cand[0] > best[0]
            best = tuple(np.where(take, c, b) for c, b in zip(cand, best))
    if best is None:
        z = np.zeros(D.shape)
        dur = np.where(moving, 0.0, Ts)
        start = _starts(dur, Ts)
        return SegmentTiming(z, z, z, z, z, dur, start, moving)
    dur, t1, t2, t3, jn = best
    a = jn * t1
    v = a * (t1 + t2)
    ta = 2 * t1 + t2
    dur = np.where(moving, dur, Ts)  # a segment that does not move lasts one step
    z = np.zeros(D.shape)
    return SegmentTiming(np.where(moving, v, 0.0), np.where(moving, a, 0.0), np.where(moving, t1, 0.0),
                         np.where(moving, ta, 0.0), np.where(moving, t3, z), dur, _starts(dur, Ts), moving)


def _starts(dur, pause):
    """Start times of segments of durations ``dur`` following each other after ``pause``."""
    if not len(dur):
        return np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(dur + pause)[:-1]])


def segment_timing(distance, angle, limits: MotionLimits) -> SegmentTiming:
    """Timing of segments of translation ``distance`` (M,) m and rotation ``angle`` (M,) rad
    (zero-length segments take no time; with ``timing="sampled"`` one step) under ``limits``.
    With ``limits="per_coordinate"`` the caller passes the largest change of one coordinate of
    each kind (module documentation)."""
    D = np.asarray(distance, dtype=float).reshape(-1)
    A = np.asarray(angle, dtype=float).reshape(-1)
    if limits.timing == "sampled":
        return _sampled_timing(D, A, limits)
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
    return SegmentTiming(v, a, np.where(moving, tj_used, 0.0), np.where(moving, ta, 0.0), tc, dur, start, moving)


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
    still = dur <= 0 if timing.moving is None else ~timing.moving[seg]
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
    if limits.timing == "sampled":
        return _sample_sampled(timing, limits.step, float(dt), max_samples)
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


def _sample_sampled(timing: SegmentTiming, step: float, dt: float, max_samples: int) -> PathSamples:
    """Samples of a profile with ``timing="sampled"``: every segment from its start to its end
    at the steps ``dt`` (``step`` a whole multiple of ``dt``), the next segment one ``step``
    later (``traj_trapez2_multipoint``: each corner sampled at the end of one segment and again
    at the start of the next). Integer sample counts, so that no rounding of times moves a
    sample off a segment's phases."""
    k = step / dt
    if abs(k - round(k)) > 1e-9 * max(k, 1.0) or round(k) < 1:
        raise ValueError(f"dt: with sampled timing the time step must divide the rounding step {step} s, got {dt} s")
    k = int(round(k))
    n = np.rint(timing.duration / dt).astype(np.int64)
    M = len(n)
    if M == 0:
        t = np.zeros(1)
        z = np.zeros(1)
        return PathSamples(t, np.zeros(1, int), z + 1.0, z, z, z, timing)
    first = np.concatenate([[0], np.cumsum(n + k)[:-1]])
    total = int(first[-1] + n[-1]) + 1
    if total > max_samples:
        raise ValueError(f"the path takes {total * dt:.4g} s: {total} samples at dt = {dt} s exceed {max_samples}; "
                         f"give a larger time step")
    idx = np.arange(total)
    seg = np.searchsorted(first, idx, side="right") - 1
    timing = SegmentTiming(timing.v, timing.a, timing.tj, timing.ta, timing.tc, timing.duration, first * dt,
                           timing.moving)
    s, sd, sdd, sddd = profile_at((idx - first[seg]) * dt, timing, seg)
    return PathSamples(idx * dt, seg, s, sd, sdd, sddd, timing)
