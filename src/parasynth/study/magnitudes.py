"""Lengths in a study far from the mechanism's scale: ``low: 160 m`` for a link length, a
workspace range of +-200 m for a mechanism of a few hundred millimetres.

A unit slip (m written where mm was meant) gives a study that loads, checks and runs, and
whose every design fails or whose workspace sample misses the mechanism. :func:`scale_warnings`
names such values. The rule: a length (a design variable's bound or value, a fixed or reference
parameter, a bound of ``evaluation.ranges``, a coordinate of ``evaluation.fixed_pose``) whose
magnitude is more than :data:`SCALE_FACTOR` times the mechanism's characteristic length is
warned about. The characteristic length (:func:`characteristic_length`) is the distance from
the base origin of the farthest joint (base anchors, and platform anchors at the home pose),
and at least the model's ``length_scale``, of the mechanism with its default parameters (the
scale the model is written at; with the study's fixed parameters when the defaults cannot be
built). Only large magnitudes are warned about: small lengths (a diameter, an offset of 0 mm,
a tolerance) are common and meaningful.
"""

from __future__ import annotations

import numpy as np

from ..mechanisms import load_mechanism, mechanism_class
from ..measures.display import fmt_quantity, unit_for_kind, written_unit

__all__ = ["SCALE_FACTOR", "characteristic_length", "scale_warnings"]

#: A length more than this many characteristic lengths is warned about.
SCALE_FACTOR = 100.0


def characteristic_length(mech) -> float:
    """The size of ``mech`` at its home pose (m): the largest distance from the base origin of a
    joint (every leg's base anchor, and its platform anchor placed by the home pose), and at
    least the model's ``length_scale``."""
    L = float(getattr(mech, "length_scale", 0.0) or 0.0)
    legs = list(getattr(mech, "legs", ()))
    if legs:
        base = np.array([leg.base for leg in legs], float)
        L = max(L, float(np.max(np.linalg.norm(base, axis=1))))
        try:
            p, R = mech.pose(np.asarray(mech.home, float))
            plat = np.asarray(p, float) + np.array([np.asarray(R, float) @ np.asarray(leg.platform, float)
                                                    for leg in legs])
            L = max(L, float(np.max(np.linalg.norm(plat, axis=1))))
        except Exception:  # a home pose that cannot be placed: the base anchors and the scale alone
            pass
    return L


def _scale_of(study) -> tuple[float, str] | None:
    for params, what in (({}, "default"), (dict(study.fixed), "fixed")):
        try:
            L = characteristic_length(load_mechanism(study.mechanism, **params))
        except Exception:  # every model error: try the next, or no check
            continue
        if np.isfinite(L) and L > 0:
            return L, what
    return None


def scale_warnings(study, factor: float = SCALE_FACTOR) -> list[str]:
    """Lengths of ``study`` (a :class:`~parasynth.study.spec.ResolvedStudy`) whose magnitude is
    more than ``factor`` times the mechanism's characteristic length, one line each with its key
    path and the value as written (module documentation); an empty list when there are none or
    the mechanism cannot be built (:func:`~parasynth.study.spec.check_study` reports that)."""
    if not (isinstance(factor, (int, float)) and np.isfinite(factor) and factor > 0):
        raise ValueError(f"factor: give a positive number of characteristic lengths, got {factor!r}")
    got = _scale_of(study)
    if got is None:
        return []
    L, what = got
    limit = factor * L
    spec = study.spec
    kinds = dict(getattr(getattr(_mech_cls(study), "Params", None), "UNITS", {}) or {})
    items = []  # (key path, SI value, value as written)
    for k, v in study.fixed.items():
        if kinds.get(k) == "length":
            items += _flat(f"fixed.{k}", v, spec.fixed.get(k))
    raw_ref = spec.reference or {}
    for k, v in (study.reference or {}).items():
        if kinds.get(k) == "length":
            items += _flat(f"reference.{k}", v, raw_ref.get(k))
    raw_vars = {v.name: v for v in spec.variables}
    for var in study.variables:
        if var.kind != "length" or var.name not in raw_vars:
            continue
        raw, path = raw_vars[var.name], study.variable_path(var.name)
        for key in ("low", "high"):
            if getattr(var, key) is not None:
                items.append((f"{path}.{key}", getattr(var, key), getattr(raw, key)))
        if raw.values:  # values written out (not those num spreads between low and high)
            items += [(f"{path}.values[{j}]", x, r) for j, (x, r) in enumerate(zip(var.values or (), raw.values))]
    ev, raw_ev = study.evaluation, spec.evaluation
    angular = _angular(study)
    for c, (lo, hi) in (ev.get("ranges") or {}).items():
        if c not in angular:
            pair = (raw_ev.ranges or {}).get(c) or (None, None)
            items += [(f"evaluation.ranges.{c}[{j}]", x, pair[j]) for j, x in enumerate((lo, hi))]
    for c, x in (ev.get("fixed") or {}).items():
        if c not in angular:
            items.append((f"evaluation.fixed_pose.{c}", x, raw_ev.fixed_pose.get(c)))
    out = []
    shown = unit_for_kind("length")
    for path, x, raw in items:
        if isinstance(x, (int, float)) and np.isfinite(x) and abs(x) > limit:
            unit = written_unit(raw, "length") or shown
            out.append(f"{path}: {raw if isinstance(raw, str) else fmt_quantity(x, unit)} is {abs(x) / L:.0f} times "
                       f"the mechanism's characteristic length ({fmt_quantity(L, unit)}, the farthest joint from the "
                       f"base origin at the home pose, {what} parameters); lengths above {factor:g} times it are "
                       f"warned about: is the unit right?")
    return out


def _flat(path, value, raw):
    if isinstance(value, (list, tuple)):
        raws = raw if isinstance(raw, (list, tuple)) and len(raw) == len(value) else [None] * len(value)
        return [item for j, (v, r) in enumerate(zip(value, raws)) for item in _flat(f"{path}[{j}]", v, r)]
    return [(path, value, raw)]


def _mech_cls(study):
    try:
        return mechanism_class(study.mechanism)
    except Exception:  # a mechanism the loader refused: no kinds, no check
        return None


def _angular(study) -> set:
    try:
        return set(load_mechanism(study.mechanism, **study.fixed).angular_coordinates)
    except Exception:  # by name, as the study loader does for a model it cannot build
        return {"alpha", "beta", "gamma", "psi", "theta", "phi"}
