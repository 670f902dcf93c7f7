"""Checks of values given through the Python API: numbers, counts and poses.

Every check names the field it checks and says what is allowed, in the style
``"<field> must be <what is allowed>, got <value>"``. They raise :class:`InputError`, a
``ValueError``, so callers that catch ``ValueError`` keep working.

Numbers are real numbers only: ``bool``, ``str``, ``bytes``, ``complex`` and ``None`` are
rejected (``True`` is not 1 m, ``"0.2"`` is not 0.2 m); NumPy scalars and 0-d arrays are
accepted. Values must be finite.

Resource limits (documented in ``docs/study-format.md``) stop a request that would exhaust
memory or time before any work is done:

* :data:`MAX_SAMPLES`: workspace samples of one evaluation (``n``, ``evaluation.samples``,
  ``final_samples``, ``--samples``);
* :data:`MAX_TRIALS`: evaluation budget of a study (``n_trials``, ``maxeval``);
* :data:`MAX_LEGS`: points one anchor pattern of a described mechanism generates (the
  description reader's ``MAX_PATTERN_POINTS``);
* :data:`MAX_POSE_MAGNITUDE`: a position coordinate beyond this (1e6 m) is outside any
  mechanism and is treated as unreachable, as NaN is (it would overflow squares of lengths).

:func:`check_engine` validates the ``engine=`` argument of the evaluations that have a compiled
path (:data:`ENGINES`: ``"compiled"``, ``"numpy"``).
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import numbers

import numpy as np

from .units import si_unit

__all__ = [
    "InputError",
    "check_number",
    "check_mechanism",
    "check_names",
    "check_count",
    "check_array",
    "check_pose_array",
    "mask_huge_poses",
    "pose_finite",
    "is_real_number",
    "ENGINES",
    "check_engine",
    "numpy_reference",
    "MAX_SAMPLES",
    "MAX_TRIALS",
    "MAX_LEGS",
    "MAX_POSE_MAGNITUDE",
    "MAX_SEED",
]

#: Largest workspace sample count of one evaluation (2**22 = 4,194,304 poses).
MAX_SAMPLES = 2**22
#: Largest evaluation budget of one study (trials or NLopt evaluations).
MAX_TRIALS = 1_000_000
#: Largest number of points one anchor pattern of a described mechanism generates (the same
#: value as ``parasynth.mechanisms.description.anchors.MAX_PATTERN_POINTS``).
MAX_LEGS = 1000
#: Largest |pose coordinate| (m) that is evaluated; beyond it a pose is unreachable.
MAX_POSE_MAGNITUDE = 1e6
#: Seeds are integers in [0, MAX_SEED] (NumPy's SeedSequence and Optuna's samplers accept them).
MAX_SEED = 2**32 - 1


class InputError(ValueError):
    """A value given through the API that is not allowed; the message names the field."""


#: Values of the ``engine=`` argument: the compiled engine (default) or the NumPy reference.
ENGINES = ("compiled", "numpy")


_FORCED: contextvars.ContextVar = contextvars.ContextVar("parasynth_engine_forced", default=None)


def check_engine(engine, arg: str = "engine") -> str:
    """Validate an engine name ("compiled" or "numpy") and return the engine to use: the
    lower-cased name, or "numpy" inside :func:`numpy_reference`."""
    if not isinstance(engine, str) or engine.lower() not in ENGINES:
        raise ValueError(f"{arg} must be one of {', '.join(ENGINES)}; got {engine!r}")
    return _FORCED.get() or engine.lower()


@contextlib.contextmanager
def numpy_reference():
    """Within the block (this thread or task), every engine entry point -- feasibility,
    margins, poses, the pose-wise indices -- evaluates with the NumPy reference, whatever
    ``engine`` it is asked for: nothing is compiled. For a handful of evaluations (checking a
    study file) that should not wait for a cold compile; the answers agree with the compiled
    path to ~1e-12 (see the agreement contracts). Also ``parasynth.engine.reference``."""
    token = _FORCED.set("numpy")
    try:
        yield
    finally:
        _FORCED.reset(token)


def is_real_number(value) -> bool:
    """True for int/float and NumPy real scalars (0-d arrays included), False for bool,
    str, bytes, complex, None and containers."""
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, np.ndarray):
        return value.ndim == 0 and value.dtype.kind in "iuf"
    return isinstance(value, numbers.Real)


def _describe(value) -> str:
    if isinstance(value, (bool, np.bool_)):
        return f"a boolean ({value!r})"
    if isinstance(value, (str, bytes)):
        return f"a string ({value!r})"
    if isinstance(value, complex) or (isinstance(value, np.generic) and np.iscomplexobj(value)):
        return f"a complex number ({value!r})"
    if value is None:
        return "None"
    return repr(value) if len(repr(value)) <= 80 else repr(value)[:77] + "..."


def _range_text(lo, hi, lo_open, hi_open, unit) -> str:
    u = f" {unit}" if unit else ""
    if lo is not None and hi is not None:
        return f"in {'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}{u}"
    if lo is not None:
        return f"{'>' if lo_open else '>='} {lo}{u}"
    if hi is not None:
        return f"{'<' if hi_open else '<='} {hi}{u}"
    return ""


def check_number(field: str, value, kind: str | None = None, lo: float | None = None, hi: float | None = None,
                 *, lo_open: bool = False, hi_open: bool = False, unit: str | None = None) -> float:
    """``value`` as a finite float in [lo, hi] (open ends with ``lo_open``/``hi_open``).

    ``kind`` ("length", "angle", "dimensionless", ...) and ``unit`` (default the SI unit of the
    kind) only word the message. Raises :class:`InputError` naming ``field``::

        >>> check_number("link_length", True, "length", 0, lo_open=True)
        Traceback (most recent call last):
        ...
        parasynth.common.validation.InputError: link_length must be a length in m > 0, got a boolean (True)
    """
    if unit is None:
        unit = si_unit(kind)
    what = f"a {kind}" if kind and kind != "dimensionless" else "a number"
    rng = _range_text(lo, hi, lo_open, hi_open, unit)
    allowed = f"{what} in {unit}" if unit else what
    allowed = f"{allowed} {rng}".rstrip()
    if not is_real_number(value):
        raise InputError(f"{field} must be {allowed}, got {_describe(value)}")
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"{field} must be finite ({allowed}), got {value!r}")
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise InputError(f"{field} must be {allowed}, got {value!r}")
    if hi is not None and (v >= hi if hi_open else v > hi):
        raise InputError(f"{field} must be {allowed}, got {value!r}")
    return v


def check_mechanism(field: str, value):
    """``value`` when it is a mechanism (has task coordinates and a feasibility test); a
    :class:`TypeError` naming ``field`` otherwise (a model's name given where the model is
    expected, a number, None)::

        >>> check_mechanism("mech", "5pus_upu")
        Traceback (most recent call last):
        ...
        TypeError: mech must be a mechanism, e.g. parasynth.load_mechanism('5pus_upu'), got a string ('5pus_upu')
    """
    if hasattr(value, "task_coordinates") and callable(getattr(value, "is_feasible", None)):
        return value
    hint = repr(value) if isinstance(value, str) else "'5pus_upu'"
    raise TypeError(f"{field} must be a mechanism, e.g. parasynth.load_mechanism({hint}), got {_describe(value)}")


def check_names(field: str, value, what: str = "constraint") -> list[str] | None:
    """``None`` (all), one name or a list of names as a list; a :class:`TypeError` naming
    ``field`` for a number, a mapping or another object that is not a list of names."""
    if value is None:
        return None
    if isinstance(value, str):
        return [value]
    if isinstance(value, (list, tuple, set, frozenset)) or (isinstance(value, np.ndarray) and value.ndim == 1):
        return list(value)
    raise TypeError(f"{field} must be a {what} name or a list of {what} names, got {_describe(value)}")


def check_count(field: str, value, lo: int = 1, hi: int | None = None, *, what: str = "an integer") -> int:
    """``value`` as an int in [lo, hi]. Integral floats (``4096.0``) are accepted; bool, str,
    non-integral and non-finite values are not. ``hi`` is a resource limit: the message says
    it is the documented maximum."""
    if not is_real_number(value):
        raise InputError(f"{field} must be {what} >= {lo}, got {_describe(value)}")
    if isinstance(value, (float, np.floating)) or (isinstance(value, np.ndarray) and value.dtype.kind == "f"):
        f = float(value)
        if not math.isfinite(f) or not f.is_integer():
            raise InputError(f"{field} must be {what} >= {lo}, got {value!r}")
        if hi is not None and f > hi:
            raise InputError(f"{field} must be at most {hi} (the documented maximum), got {value!r}")
        value = int(f)
    v = int(value)
    if v < lo:
        raise InputError(f"{field} must be {what} >= {lo}, got {value!r}")
    if hi is not None and v > hi:
        raise InputError(f"{field} must be at most {hi} (the documented maximum), got {value!r}")
    return v


def check_array(field: str, value, shape: tuple | None = None, kind: str | None = None, lo=None, hi=None) -> np.ndarray:
    """``value`` as a finite float array (of ``shape`` where given, -1 for any length) whose
    entries are real numbers in [lo, hi]; strings, booleans and complex entries are rejected."""
    if isinstance(value, (str, bytes)) or value is None or isinstance(value, (bool, np.bool_)):
        raise InputError(f"{field} must be an array of numbers, got {_describe(value)}")
    try:
        a = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(f"{field} must be an array of numbers, got {_describe(value)}") from None
    if a.dtype.kind not in "iuf":
        if a.dtype.kind == "O":
            bad = [x for x in a.ravel() if not is_real_number(x)][:1]
            if bad:
                raise InputError(f"{field} must contain numbers only, got {_describe(bad[0])}")
            a = a.astype(float)
        else:
            kinds = {"b": "booleans", "c": "complex numbers", "U": "strings", "S": "strings"}
            raise InputError(f"{field} must contain real numbers only, got {kinds.get(a.dtype.kind, a.dtype)}")
    a = a.astype(float)
    if shape is not None:
        ok = len(shape) == a.ndim and all(s in (-1, t) for s, t in zip(shape, a.shape))
        if not ok:
            raise InputError(f"{field} must have shape {shape}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{field} must be finite, got {value!r}")
    if lo is not None and np.any(a < lo):
        raise InputError(f"{field} must be >= {lo}, got {value!r}")
    if hi is not None and np.any(a > hi):
        raise InputError(f"{field} must be <= {hi}, got {value!r}")
    return a


def check_pose_array(field: str, X) -> np.ndarray:
    """Poses as a float array without checking the shape: real numbers only (strings, booleans,
    complex numbers and None rejected with ``field`` named). NaN, infinite and huge
    coordinates are kept; the models mask them as unreachable (see :func:`pose_finite`)."""
    if isinstance(X, (str, bytes)) or X is None or isinstance(X, (bool, np.bool_)):
        raise InputError(f"{field} must be an array of numbers (SI: m, rad), got {_describe(X)}")
    if isinstance(X, np.ndarray) and X.dtype.kind in "f":
        return X.astype(float, copy=False)
    try:
        a = np.asarray(X)
    except (TypeError, ValueError):
        raise InputError(f"{field} must be an array of numbers (SI: m, rad), got {_describe(X)}") from None
    kind = a.dtype.kind
    if kind in "iuf":
        return a.astype(float)
    if kind == "O":
        bad = [x for x in a.ravel() if not is_real_number(x)][:1]
        if not bad:
            return a.astype(float)
        raise InputError(f"{field} must contain numbers only (SI: m, rad), got {_describe(bad[0])}")
    kinds = {"b": "booleans", "c": "complex numbers", "U": "strings", "S": "strings"}
    raise InputError(f"{field} must contain real numbers only (SI: m, rad), got {kinds.get(kind, str(a.dtype))}")


def pose_finite(X: np.ndarray) -> np.ndarray:
    """(N,) bool: every coordinate finite and within :data:`MAX_POSE_MAGNITUDE`."""
    with np.errstate(invalid="ignore"):
        return np.all(np.isfinite(X) & (np.abs(X) <= MAX_POSE_MAGNITUDE), axis=-1)


def mask_huge_poses(X: np.ndarray, columns=None) -> np.ndarray:
    """``X`` with every coordinate beyond :data:`MAX_POSE_MAGNITUDE` replaced by NaN (a copy
    when any is), so that the models mask such poses as unreachable as they do NaN poses;
    squares of 1e308 m overflow to inf and would otherwise reach the kinematics. ``columns``
    (bool per task coordinate) limits the check to some coordinates: the models check their
    lengths; a huge angle is a whole number of turns plus a finite angle and stays defined."""
    with np.errstate(invalid="ignore"):
        huge = np.abs(X) > MAX_POSE_MAGNITUDE
    if columns is not None and X.ndim >= 1 and X.shape[-1] == len(columns):
        huge &= np.asarray(columns, dtype=bool)
    if not np.any(huge):
        return X
    X = np.array(X, dtype=float, copy=True)
    X[huge] = np.nan
    return X

