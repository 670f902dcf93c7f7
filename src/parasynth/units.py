"""Quantities with explicit units at the YAML/CLI boundary ("205 mm", "15 deg").

Inside the library everything is SI (m, rad, N, kg, s). A unit-bearing field given as a bare
number is an error, not a guess. Parsing and dimension checks are delegated to pint.
"""

from __future__ import annotations

import math
import re
from functools import lru_cache

__all__ = ["UNIT_KINDS", "parse_quantity", "format_quantity", "QuantityError"]

#: Kinds of quantities and their SI unit (pint spelling) and pint dimensionality.
UNIT_KINDS = {
    "length": ("m", "[length]"),
    "angle": ("rad", ""),
    "force": ("N", "[force]"),
    "mass": ("kg", "[mass]"),
    "time": ("s", "[time]"),
    "torque": ("N*m", "[force] * [length]"),
    "stiffness": ("N/m", "[force] / [length]"),
    "rotational_stiffness": ("N*m/rad", "[force] * [length]"),
    "pressure": ("Pa", "[pressure]"),
    "dimensionless": ("", ""),
}

#: How quantities are shown to people (reports, summaries).
DISPLAY_UNITS = {"length": "mm", "angle": "deg", "force": "N", "mass": "kg", "time": "s", "torque": "N*m",
                 "stiffness": "N/m", "rotational_stiffness": "N*m/rad", "pressure": "GPa"}


class QuantityError(ValueError):
    """A value without a required unit, with the wrong dimension, or unparsable."""


# "<number> <unit>" in the commonest units, converted without pint (importing pint and
# building its registry takes about half a second at every start): {unit: (kind, factor to
# SI)}. The factors reproduce pint's conversions exactly (tests/test_units.py compares them);
# anything else -- other units, prefixes, compound units, "nan", errors -- goes to pint.
_FAST_UNITS = {"m": ("length", 1.0), "mm": ("length", 1e-3), "cm": ("length", 1e-2),
               "rad": ("angle", 1.0), "deg": ("angle", math.pi / 180), "N": ("force", 1.0), "kg": ("mass", 1.0),
               "s": ("time", 1.0), "Pa": ("pressure", 1.0), "MPa": ("pressure", 1e6), "GPa": ("pressure", 1e9)}
_FAST = re.compile(r"\s*(-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z]+)\s*")


def _fast_quantity(value: str, kind: str, field: str = "value"):
    """SI magnitude of ``value`` when it is a plain number and one unit of ``kind`` in
    :data:`_FAST_UNITS` (:class:`QuantityError`, as pint's path, for a unit there of another
    dimension), else None (pint decides)."""
    m = _FAST.fullmatch(value)
    if m is None:
        return None
    unit = _FAST_UNITS.get(m.group(2))
    if unit is None or (unit[0] != kind and kind == "dimensionless"):  # pint takes angles as dimensionless
        return None
    if unit[0] != kind:  # a unit of another dimension: pint's answer
        if kind == "angle":
            raise QuantityError(f"{field}: {value!r} is not an angle (use deg or rad)")
        raise QuantityError(f"{field}: {value!r} is not a {kind} (expected units like {DISPLAY_UNITS[kind]})")
    v = float(m.group(1))
    return v if unit[1] == 1.0 else v * unit[1]


@lru_cache(maxsize=1)
def _ureg():
    import pint  # lazy: pint is slow to import; only quantities written with a unit need it

    return pint.UnitRegistry()


def parse_quantity(value, kind: str, field: str = "value") -> float:
    """Parse ``value`` ("205 mm", "15 deg", "0.2 m") as a ``kind`` and return SI magnitude.

    Dimensionless kinds accept plain numbers. Raises :class:`QuantityError` naming ``field``
    for a bare number where a unit is required, a wrong dimension, an unparsable string or a
    value that is not finite (``nan mm``, ``inf deg``: a NaN bound would make every comparison
    false, so a constraint would never bind).
    """
    v = _parse_quantity(value, kind, field)
    if not math.isfinite(v):
        if kind == "dimensionless":
            raise QuantityError(f"{field}: {value!r} is not a finite number")
        raise QuantityError(f"{field}: {value!r} is not a finite {kind}; give a number with a unit, "
                            f"e.g. '10 {DISPLAY_UNITS[kind]}'")
    # Decimal unit conversion leaves binary noise (205 mm -> 0.20500000000000002 m); 15
    # significant digits are exact for every decimal input of up to 15 digits. Angles in
    # degrees have no short decimal value in rad and are left as computed.
    return v if kind == "angle" else float(f"{v:.15g}")


def _parse_quantity(value, kind: str, field: str) -> float:
    if kind not in UNIT_KINDS:
        raise ValueError(f"unknown quantity kind {kind!r}; allowed: {sorted(UNIT_KINDS)}")
    si, dim = UNIT_KINDS[kind]
    if isinstance(value, bool):
        raise QuantityError(f"{field}: expected a {kind}, got a boolean {value!r}")
    if isinstance(value, complex):
        raise QuantityError(f"{field}: expected a {kind}, got a complex number {value!r}")
    if isinstance(value, (int, float)):
        if kind == "dimensionless":
            return float(value)
        raise QuantityError(
            f"{field}: a bare number ({value!r}) is not allowed for a {kind}; give a unit, "
            f"e.g. '{value} {DISPLAY_UNITS[kind]}'"
        )
    if not isinstance(value, str):
        raise QuantityError(f"{field}: expected a {kind} such as '10 {DISPLAY_UNITS.get(kind, '')}', got {value!r}")
    if len(value) > 200:
        raise QuantityError(f"{field}: {value[:40]!r}... is too long for a {kind}")
    fast = _fast_quantity(value, kind, field)
    if fast is not None:
        return fast
    ureg = _ureg()
    try:
        q = ureg.Quantity(value.strip())
    except Exception as e:  # pint raises several error types
        raise QuantityError(f"{field}: cannot parse {value!r} as a {kind} ({e})") from None
    if kind == "angle":
        if q.dimensionless and q.unitless and kind != "dimensionless":
            raise QuantityError(f"{field}: {value!r} has no unit; give an angle such as '15 deg' or '0.2 rad'")
        try:
            return float(q.to("rad").magnitude)
        except Exception:
            raise QuantityError(f"{field}: {value!r} is not an angle (use deg or rad)") from None
    if kind == "dimensionless":
        if not q.dimensionless:
            raise QuantityError(f"{field}: {value!r} must be dimensionless")
        return float(q.to("").magnitude)
    if q.unitless:
        raise QuantityError(f"{field}: {value!r} has no unit; give a {kind} such as '10 {DISPLAY_UNITS[kind]}'")
    if not q.check(dim):
        raise QuantityError(f"{field}: {value!r} is not a {kind} (expected units like {DISPLAY_UNITS[kind]})")
    return float(q.to(si).magnitude)


def format_quantity(value_si: float, kind: str, digits: int = 4) -> str:
    """SI value as a string in display units, e.g. 0.205 m -> '205 mm'."""
    if kind in (None, "dimensionless", "") or kind not in UNIT_KINDS:
        return f"{value_si:.{digits}g}"
    unit = DISPLAY_UNITS[kind]
    ureg = _ureg()
    v = ureg.Quantity(value_si, UNIT_KINDS[kind][0]).to(unit).magnitude
    return f"{v:.{digits}g} {unit}"
