"""How quantities are shown to people: display units per quantity kind, numbers without float noise.

Inside the library every value is SI (m, rad, N, m^3, ...). Tables, figure axes and console
summaries show each quantity in the unit a designer reads: the display unit of its kind in the
units table :data:`parasynth.common.units.UNIT_KINDS` (length in mm, angle in deg, area in cm^2, volume
in cm^3, pressure in GPa, force, stiffness, torque, mass and time in SI).

A quantity's kind comes from the measure registry (``Measure.kind_of(settings)``, the kind,
which may follow a setting as ``stiffness_min``'s follows ``part``, or ``Measure.unit``) for
objectives and design constraints, and from the design variable's kind for variables. The
workspace measures in "sampled units" (a volume in the product of the sampled coordinates'
units) get a compound unit: ``cm^3`` for three position coordinates, ``cm^3*deg^2`` for three
positions and two angles, and so on. The units themselves (:class:`Unit`, the display unit of each
kind, compound units, column suffixes) live in the one units layer, :mod:`parasynth.common.units`;
this module decides which unit a study's column carries.

Numbers are rounded to a number of significant digits (default 4) and written without
trailing zeros or exponent for ordinary magnitudes: ``0.20500000000000002 m`` -> ``205 mm``.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..common.columns import MARGIN, ROBUST_SE, STDERR, nominal
from ..common.units import (ACTUATOR_KINDS, NONE, UNITS, Unit, actuator_unit_kind, compound_unit, parse_quantity,
                            unit_for_kind, unit_for_si)
from ..mechanisms import mechanism_class
from .objectives import OBJECTIVES

__all__ = ["Unit", "UNITS", "unit_for_kind", "unit_for_si", "quantity_unit", "fmt_number", "fmt_quantity",
           "fmt_mean_se", "fmt_value", "column_header", "text_table", "fmt_column_value", "fmt_design",
           "fmt_evaluation", "reference_name", "reference_short", "written_unit", "study_unit", "fmt_study_design",
           "actuators_of", "study_actuators", "measure_kind"]


# -- what the actuators are ----------------------------------------------------------------------
def _class_actuators(cls) -> str | None:
    desc = getattr(cls, "description", None)
    return getattr(desc, "actuator_kind", None)


def actuators_of(mech_cls=None, structures=None) -> str | None:
    """What the actuators of a study's mechanism are: "length" (telescopic legs, sliders),
    "angle" (cranks), "mixed" or None (unknown). Over structures (``structures``: a study's
    structure set, ``.structures`` {label: structure}) the structures together: "mixed" when
    some are driven by cranks and others by linear actuators, as a column over them would be."""
    if structures is not None:
        kinds = set()
        for s in getattr(structures, "structures", {}).values():
            try:
                cls = s.mechanism_class
                kinds.add(_class_actuators(cls() if callable(cls) and not isinstance(cls, type) else cls))
            except Exception:  # a structure whose class cannot be built: its actuators are unknown
                kinds.add(None)
    else:
        kinds = {_class_actuators(mech_cls)}
    kinds.discard(None)
    if not kinds:
        return None
    return kinds.pop() if len(kinds) == 1 else "mixed"


def study_actuators(study) -> str | None:
    """:func:`actuators_of` a resolved study's mechanism (or structures); None when unknown."""
    setup = getattr(study, "structures", None)
    if setup is not None:
        return actuators_of(structures=setup)
    try:
        return actuators_of(mechanism_class(study.mechanism))
    except Exception:  # a mechanism that cannot be loaded: unknown actuators
        return None


def measure_kind(study, measure, settings: dict | None = None) -> str | None:
    """The quantity kind of ``measure``'s value in ``study``: its kind for these settings, an
    actuator kind resolved by the study's actuators (a largest actuator force on cranks is a
    torque, N*m; ``ValueError`` on mixed actuators)."""
    kind = measure.kind_of(settings)
    if kind in ACTUATOR_KINDS:
        return actuator_unit_kind(kind, study_actuators(study), measure.name)
    return kind


# -- which unit for a study column ---------------------------------------------------------------
def _sampled_coordinates(study, settings: dict) -> tuple[list[str], set]:
    """Names of the coordinates a workspace measure samples, and the angular ones, from the
    mechanism's class (its declared task coordinates and default ranges: nothing is built)."""
    ranges = settings.get("ranges") or study.evaluation.get("ranges")
    try:
        cls = mechanism_class(study.mechanism)
        angular = set(cls.angular_coordinates)
        if not ranges:
            desc = getattr(cls, "description", None)
            ranges = list(desc.task.ranges) if desc is not None else list(cls.task_coordinates)
    except Exception:  # a mechanism that cannot be loaded: fall back on the usual angle names
        angular = {"alpha", "beta", "gamma", "psi", "theta", "phi"}
    return list(ranges or ()), angular


def _sampled_unit(study, measure, settings: dict) -> Unit:
    coords, angular = _sampled_coordinates(study, settings)
    if not coords:
        return NONE
    if measure.name == "inscribed_box_size":
        axis = settings.get("axis", "z")
        return UNITS["angle"] if axis in angular else UNITS["length"]
    if measure.name == "singularity_free_radius":  # a radius in coordinates of one unit
        c = settings.get("coords", "position")
        named = [x.strip() for x in c.split(",")] if isinstance(c, str) and c not in ("position", "all") else []
        return UNITS["angle"] if named and named[0] in angular else UNITS["length"]
    if settings.get("coords", "position") == "position" and "coords" in measure.settings:
        coords = [c for c in coords if c not in angular]
    na = sum(1 for c in coords if c in angular)
    return compound_unit(len(coords) - na, na)


def quantity_unit(study, name: str) -> Unit:
    """Display unit of a result column of ``study``: a design variable (by name), an objective or
    design constraint (by label, also ``<label>_stderr``), or a constraint margin
    (``<label>_margin``, in the constraint's unit). Other columns: no unit."""
    for suffix in (STDERR, MARGIN, ROBUST_SE):
        if name.endswith(suffix) and quantity_known(study, name[: -len(suffix)]):
            return quantity_unit(study, name[: -len(suffix)])
    for o in study.constraints:  # a chance constraint's nominal value is the measure's, its value a fraction
        if name == nominal(o.label) and getattr(o, "robust", None) is not None:
            return measure_unit(study, o.name, getattr(o, "settings", {}) or {})
    for o in study.objectives:
        if name == nominal(o.label) and getattr(o, "robust", None) is not None:
            return quantity_unit(study, o.label)
    for v in study.variables:
        if v.name == name:
            return unit_for_kind(v.kind) if v.type != "categorical" or v.kind else NONE
    for o in list(study.objectives) + list(study.constraints):
        if o.label == name:
            if getattr(o, "probability", None) is not None:
                return NONE  # a chance constraint: a fraction of scatter draws
            return measure_unit(study, o.name, getattr(o, "settings", {}) or {})
    return NONE


def quantity_known(study, name: str) -> bool:
    return any(v.name == name for v in study.variables) or any(
        o.label == name or (getattr(o, "robust", None) is not None and name == nominal(o.label))
        for o in list(study.objectives) + list(study.constraints))


def measure_unit(study, measure_name: str, settings: dict | None = None) -> Unit:
    """Display unit of a registered measure's value (with the study's settings for the sampled units)."""
    m = OBJECTIVES.get(measure_name)
    if m is None:
        return NONE
    try:  # a kind that follows a setting (stiffness_min's part) or the actuators (N or N*m)
        kind = measure_kind(study, m, settings)
    except ValueError:  # an actuator kind on mixed actuators (refused when the study is loaded)
        return NONE
    if kind:
        return unit_for_kind(kind)
    if m.unit in ("sampled units", "sampled unit"):
        return _sampled_unit(study, m, settings or {})
    return unit_for_si(m.unit)


_WRITTEN = re.compile(r"\s*[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?\s*([^\s0-9].*?)\s*")


def written_unit(value, kind: str | None) -> Unit | None:
    """The unit a study file writes ``value`` in (``"160 m"`` -> m, ``"15 deg"`` -> deg) as a
    display unit of ``kind``; None for a bare number, an unparsable value or another kind."""
    if not kind or not isinstance(value, str):
        return None
    m = _WRITTEN.fullmatch(value)
    if m is None:
        return None
    try:
        si = parse_quantity(f"1 {m.group(1)}", kind)
    except ValueError:
        return None
    return Unit(m.group(1), 1.0 / si) if si > 0 else None


def study_unit(study, name: str) -> Unit:
    """The unit design variable ``name`` is written in in the study file (the first of its
    ``low``, ``high``, ``values`` and ``choices`` that has one: a study in m is answered in m),
    else the display unit of its column (:func:`quantity_unit`)."""
    var = next((v for v in study.variables if v.name == name), None)
    spec = next((v for v in getattr(getattr(study, "spec", None), "variables", ()) if v.name == name), None)
    if var is not None and spec is not None:
        for x in (spec.low, spec.high, *(spec.values or ()), *(spec.choices or ())):
            u = written_unit(x, var.kind)
            if u is not None:
                return u
    return quantity_unit(study, name)


def fmt_study_design(study, values: dict) -> str:
    """``{link_length=160 mm, slider_radius=100 mm}``: a design's values (SI) in the units the
    study file writes them in (:func:`study_unit`), for messages about the study."""
    return "{" + ", ".join(f"{k}={fmt_quantity(x, study_unit(study, k))}" for k, x in values.items()) + "}"


def column_header(study, name: str) -> str:
    """``name [unit]`` for a result column."""
    return quantity_unit(study, name).label(name)


# -- numbers --------------------------------------------------------------------------------------
def fmt_number(x, digits: int = 4) -> str:
    """A number rounded to ``digits`` significant digits, without float noise or trailing zeros
    (``205.00000000000003`` -> ``205``, ``0.1 + 0.2`` -> ``0.3``). Integers and booleans as they
    are; NaN as an empty string; magnitudes below 1e-4 or from 1e9 in exponent form."""
    if x is None:
        return ""
    if isinstance(x, (bool, np.bool_)):
        return str(bool(x))
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, str):
        return x
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if math.isnan(x):
        return ""
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0:
        return "0"
    if abs(x) < 1e-4 or abs(x) >= 1e9:
        r = float(f"{x:.{digits}g}")
        return np.format_float_scientific(r, unique=True, trim="-", exp_digits=1).replace("e+", "e")
    r = float(f"{x:.{digits}g}")
    s = np.format_float_positional(r, unique=True, trim="-")
    return "0" if s in ("-0", "0") else s


def fmt_value(x, unit: Unit, digits: int = 4) -> str:
    """An SI value in ``unit`` without the symbol (table cells, tick labels)."""
    if isinstance(x, (bool, np.bool_, str)) or x is None:
        return fmt_number(x, digits)
    try:
        return fmt_number(float(x) * unit.factor, digits)
    except (TypeError, ValueError):
        return str(x)


def fmt_quantity(x, unit_or_kind, digits: int = 4) -> str:
    """An SI value with its display unit: ``fmt_quantity(0.205, "length")`` -> ``'205 mm'``."""
    unit = unit_or_kind if isinstance(unit_or_kind, Unit) else unit_for_kind(unit_or_kind)
    s = fmt_value(x, unit, digits)
    return f"{s} {unit.symbol}" if unit.symbol and s else s


def fmt_mean_se(mean, se, unit: Unit = NONE, with_unit: bool = False) -> str:
    """``mean ± se`` in display units, the standard error with two significant digits and the
    mean rounded to the same decimal place (``0.19167, 0.0013628`` in mm -> ``191.7 ± 1.4``).
    Without a standard error (NaN: one repeat) the mean alone with 4 significant digits."""
    m = float(mean) * unit.factor
    if not np.isfinite(m):
        return ""
    sfx = f" {unit.symbol}" if with_unit and unit.symbol else ""
    s = float(se) * unit.factor if se is not None else float("nan")
    if not np.isfinite(s):
        return fmt_number(m) + sfx
    if s == 0:
        return f"{fmt_number(m)} ± 0{sfx}"
    place = 1 - int(math.floor(math.log10(abs(s))))  # decimals that keep 2 significant digits of se
    if place <= 0:
        q = 10.0 ** (-place)
        ms, ss = fmt_number(round(m / q) * q, 15), fmt_number(round(s / q) * q, 15)
    else:
        if place > 10:
            return f"{fmt_number(m, 6)} ± {fmt_number(s, 2)}{sfx}"
        ms, ss = f"{m:.{place}f}", f"{s:.{place}f}"
    return f"{ms} ± {ss}{sfx}"


def text_table(study, df, columns) -> str:
    """Plain-text table of ``columns`` of a results table: headers with display units, values
    in display units without float noise (console summaries)."""
    import pandas as pd  # lazy: pandas is slow to import; only console tables need it

    out = pd.DataFrame(index=df.index)
    for c in columns:
        if c not in df:
            continue
        u = quantity_unit(study, c)
        out[u.label(c)] = [fmt_value(x, u) for x in df[c]]
    return out.to_string(index=False)


def fmt_column_value(study, name: str, x, digits: int = 4) -> str:
    """Value of result column ``name`` of ``study`` with its display unit (``205 mm``)."""
    return fmt_quantity(x, quantity_unit(study, name), digits)


def fmt_design(study, values: dict) -> str:
    """``link_length = 205 mm, slider_radius = 135 mm`` for a design's values (SI)."""
    return ", ".join(f"{k} = {fmt_column_value(study, k, x)}" for k, x in values.items())


def fmt_evaluation(study) -> str:
    """The study's evaluation settings in display units, one line."""
    ev = study.evaluation
    parts = [f"{ev.get('method')} sampling", f"{ev.get('n')} samples", f"seed {ev.get('seed')}"]
    ranges, fixed = ev.get("ranges"), ev.get("fixed")
    angular = _sampled_coordinates(study, {})[1] if ranges or fixed else set()

    def q(k, x):
        u = UNITS["angle"] if k in angular else UNITS["length"]
        return fmt_quantity(x, u) if isinstance(x, (int, float, np.floating)) else str(x)

    if ranges:
        parts.append("ranges " + ", ".join(f"{k} [{q(k, lo)}, {q(k, hi)}]" for k, (lo, hi) in ranges.items()))
    if isinstance(fixed, dict) and fixed:
        parts.append("fixed pose " + ", ".join(f"{k} = {q(k, x)}" for k, x in fixed.items()))
    if ev.get("constraints"):
        cons = ev["constraints"]
        parts.append("pose constraints " + (", ".join(map(str, cons)) if isinstance(cons, (list, tuple)) else str(cons)))
    if ev.get("final_samples"):
        parts.append(f"final re-evaluation: top {ev.get('final_top')} with {ev['final_samples']} samples x "
                     f"{ev.get('final_repeats')} seeds")
    return "; ".join(parts)


def reference_name(study, capital: bool = False, with_source: bool = False) -> str:
    """What the study's reference design is: its ``reference.label`` ("the paper's design")
    or "the reference design"; ``capital`` for the start of a sentence or a heading,
    ``with_source`` adds ``reference.source`` in parentheses."""
    name = getattr(study, "reference_label", None) or "the reference design"
    if capital:
        name = name[:1].upper() + name[1:]
    src = getattr(study, "reference_source", None)
    if with_source and src:
        name += f" ({src})"
    return name


def reference_short(study) -> str:
    """The reference design's name for a table row or a legend entry, without its article
    ("paper's design", "reference design")."""
    name = reference_name(study)
    for art in ("the ", "The ", "a ", "A ", "an ", "An "):
        if name.startswith(art):
            return name[len(art):]
    return name
