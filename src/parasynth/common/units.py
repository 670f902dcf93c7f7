"""Quantities with explicit units at the YAML/CLI boundary ("205 mm", "15 deg"), and the one
table of units the library uses.

Inside the library everything is SI (m, rad, N, kg, s). A unit-bearing field given as a bare
number is an error, not a guess. Parsing and dimension checks are delegated to pint.

:data:`UNIT_KINDS` is the only table of units: for each kind of quantity its SI unit (pint
spelling), pint dimensionality, display unit and display factor (display value = SI value *
factor). Everything else is derived from it here or in the modules that use it: the display
units of reports and summaries (:mod:`parasynth.measures.display`), the SI unit strings measures
declare (:data:`SI_UNIT_KINDS`), the unit literals of description expressions
(:data:`LITERAL_UNITS`) and the SI suffixes of CSV column names (:data:`DISPLAY_TO_SI`).
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

__all__ = ["UnitKind", "UNIT_KINDS", "DISPLAY_UNITS", "SI_UNIT_KINDS", "LITERAL_UNITS", "DISPLAY_TO_SI",
           "si_unit", "parse_quantity", "format_quantity", "QuantityError", "Unit", "NONE", "UNITS", "unit_for_kind",
           "unit_for_si", "compound_unit", "si_compound", "column_suffix", "in_display", "format_pose",
           "ACTUATOR_KINDS", "actuator_unit_kind", "actuators_summary"]


class UnitKind(NamedTuple):
    """One kind of quantity: ``display value = SI value * factor``."""

    si: str  #: SI unit, pint spelling ('' for a pure number)
    dimensionality: str  #: pint dimensionality ('' for dimensionless, and for angles)
    display: str  #: the unit people read in reports and summaries ('' for a pure number)
    factor: float  #: SI -> display


#: Kinds of quantities: SI unit, pint dimensionality, display unit, SI -> display factor.
UNIT_KINDS = {
    "length": UnitKind("m", "[length]", "mm", 1e3),
    "angle": UnitKind("rad", "", "deg", 180.0 / math.pi),
    "area": UnitKind("m^2", "[length] ** 2", "cm^2", 1e4),
    "volume": UnitKind("m^3", "[length] ** 3", "cm^3", 1e6),
    "force": UnitKind("N", "[force]", "N", 1.0),
    "stiffness": UnitKind("N/m", "[force] / [length]", "N/m", 1.0),
    "rotational_stiffness": UnitKind("N*m/rad", "[force] * [length]", "N*m/rad", 1.0),
    "pressure": UnitKind("Pa", "[pressure]", "GPa", 1e-9),
    "torque": UnitKind("N*m", "[force] * [length]", "N*m", 1.0),
    "mass": UnitKind("kg", "[mass]", "kg", 1.0),
    "time": UnitKind("s", "[time]", "s", 1.0),
    "speed": UnitKind("m/s", "[length] / [time]", "m/s", 1.0),
    "angular_speed": UnitKind("rad/s", "1 / [time]", "rad/s", 1.0),
    "power": UnitKind("W", "[power]", "W", 1.0),
    "dimensionless": UnitKind("", "", "", 1.0),
}

#: Kinds of quantities that follow what a mechanism's actuators are: {kind: {actuators: kind}}.
#: The actuators are "length" (telescopic legs and sliders: forces in N, speeds in m/s) or
#: "angle" (cranks, the revolute actuators of RUS legs: torques in N*m, speeds in rad/s); a
#: mechanism with both is "mixed", and a measure of such a kind is refused on it
#: (:func:`actuator_unit_kind`): its largest value would compare newtons with newton-metres.
ACTUATOR_KINDS = {
    "actuator_force": {"length": "force", "angle": "torque"},
    "actuator_speed": {"length": "speed", "angle": "angular_speed"},
}

#: Other spellings of SI units that measures declare ("N m" for N*m, "1" for a pure number).
_SI_ALIASES = {"N m": "torque", "Nm": "torque", "1": "dimensionless"}

#: Unit literals of description expressions ("135 mm" inside an expression): {unit: (kind,
#: unit -> SI factor)}. Any unit works in a quantity on its own (pint parses it).
LITERAL_UNITS = {"m": ("length", 1.0), "cm": ("length", 1e-2), "mm": ("length", 1e-3), "um": ("length", 1e-6),
                 "µm": ("length", 1e-6), "deg": ("angle", math.pi / 180.0), "rad": ("angle", 1.0)}

#: Plain units of the other kinds that quantities are commonly written in: with the literals
#: above (micrometres aside), what :func:`parse_quantity` converts without pint.
_OTHER_PLAIN_UNITS = {"N": ("force", 1.0), "kg": ("mass", 1.0), "s": ("time", 1.0), "Pa": ("pressure", 1.0),
                      "MPa": ("pressure", 1e6), "GPa": ("pressure", 1e9)}

# -- derived -------------------------------------------------------------------------------------
#: Display unit of each kind with a unit (reports, summaries, examples in messages).
DISPLAY_UNITS = {k: u.display for k, u in UNIT_KINDS.items() if k != "dimensionless"}

#: SI unit strings (as measures declare them: "m", "m^3", "N*m", "N m", "1", "") -> kind.
SI_UNIT_KINDS = {**{u.si: k for k, u in UNIT_KINDS.items()}, **_SI_ALIASES}


def _base(unit: str) -> str:
    return unit.partition("^")[0]


#: Display unit (without its power: "cm" of "cm^3") -> SI unit ("m"), where the two differ.
DISPLAY_TO_SI = {_base(u.display): _base(u.si) for u in UNIT_KINDS.values() if u.display != u.si}


def si_unit(kind: str | None) -> str:
    """The SI unit of ``kind`` ('' for a pure number, ``None`` or an unknown kind)."""
    u = UNIT_KINDS.get(kind or "")
    return u.si if u else ""


def actuators_summary(kinds) -> str | None:
    """What actuators of the kinds ``kinds`` (a mechanism's ``actuator_kinds.values()``:
    "length", "slider", "angle") are together: "length", "angle", "mixed", or None for none."""
    ks = {"angle" if k == "angle" else "length" for k in kinds}
    if not ks:
        return None
    return ks.pop() if len(ks) == 1 else "mixed"


def actuator_unit_kind(kind: str | None, actuators: str | None, what: str = "measure") -> str | None:
    """The quantity kind of ``kind`` on a mechanism whose actuators are ``actuators`` ("length",
    "angle", "mixed" or None when unknown): an actuator kind of :data:`ACTUATOR_KINDS` resolved
    (``actuator_force`` on cranks -> ``torque``; unknown actuators: as for linear ones), any other
    kind as it is. ``ValueError`` naming ``what`` for an actuator kind on mixed actuators."""
    table = ACTUATOR_KINDS.get(kind or "")
    if table is None:
        return kind
    if actuators == "mixed":
        raise ValueError(f"{what}: the mechanism's actuators are both linear (N, m/s) and cranks (N*m, rad/s), "
                         f"so one largest value of an {kind.replace('_', ' ')} would compare different units; "
                         f"allowed on mechanisms whose actuators are all linear or all cranks")
    return table.get(actuators or "length", table["length"])


# -- display units and compound units -------------------------------------------------------------
@dataclass(frozen=True)
class Unit:
    """A display unit: ``display value = SI value * factor``; ``symbol`` is empty for pure numbers."""

    symbol: str
    factor: float = 1.0

    def __call__(self, value_si):
        return value_si * self.factor

    def label(self, name: str) -> str:
        """``name [symbol]`` (``name`` alone for a pure number)."""
        return f"{name} [{self.symbol}]" if self.symbol else name


NONE = Unit("", 1.0)

#: Display unit of each quantity kind (from :data:`UNIT_KINDS`).
UNITS = {k: Unit(u.display, u.factor) if u.display else NONE for k, u in UNIT_KINDS.items()}

_POWER = {1: "", 2: "^2", 3: "^3"}
#: Kind of a product of 1, 2, 3 lengths.
_LENGTH_POWER = {1: "length", 2: "area", 3: "volume"}


def unit_for_kind(kind: str | None) -> Unit:
    """Display unit of a quantity kind (``None`` or an unknown kind: shown as a plain number)."""
    return UNITS.get(kind or "dimensionless", NONE)


def unit_for_si(unit: str | None) -> Unit:
    """Display unit for a value declared in the SI unit string ``unit`` ("m", "m^3", "N", "1", ...).
    Unknown strings are kept as they are (factor 1)."""
    if unit is None:
        return NONE
    u = unit.strip()
    if u in SI_UNIT_KINDS:
        return UNITS[SI_UNIT_KINDS[u]]
    if u == "mixed":
        return NONE
    return Unit(u, 1.0)


def compound_unit(n_length: int, n_angle: int) -> Unit:
    """Display unit of a product of ``n_length`` lengths and ``n_angle`` angles: lengths in mm
    for one, cm^2 / cm^3 for two / three (m^n beyond), angles in deg."""
    parts, factor = [], 1.0
    if n_length in _LENGTH_POWER:
        u = UNITS[_LENGTH_POWER[n_length]]
        parts.append(u.symbol)
        factor *= u.factor
    elif n_length > 3:
        parts.append(f"{UNIT_KINDS['length'].si}^{n_length}")
    if n_angle:
        parts.append(f"{UNITS['angle'].symbol}{_POWER.get(n_angle, f'^{n_angle}')}")
        factor *= UNITS["angle"].factor ** n_angle
    return Unit("*".join(parts), factor)


def si_compound(units) -> str:
    """The SI unit of a product of quantities in the SI ``units`` ("m", "rad", ...) as the
    workspace measures state it: ``("m", "m", "m", "rad", "rad")`` -> ``"m^3 rad^2"``, ``"1"``
    for none (lengths first, then angles, then any other unit in order of appearance)."""
    return _si_compound(tuple(units))


@functools.lru_cache(maxsize=256)
def _si_compound(units: tuple) -> str:
    units = [u for u in units if u not in ("", "1")]
    order = [UNIT_KINDS["length"].si, UNIT_KINDS["angle"].si] + [u for u in dict.fromkeys(units)
                                                                  if u not in ("m", "rad")]
    parts = []
    for sym in order:
        k = units.count(sym)
        if k:
            parts.append(sym if k == 1 else f"{sym}^{k}")
    return " ".join(parts) or "1"


def column_suffix(unit: Unit) -> str:
    """The SI unit of a display unit as a column-name suffix ('' for a pure number): 'm' for mm,
    'rad' for deg, 'm3' for cm^3, 'm3_rad2' for cm^3*deg^2, 'N_per_m' for N/m, 'Pa' for GPa --
    an identifier whatever a measure declares as its unit (letters, digits, '_')."""
    if not unit.symbol:
        return ""
    parts = []
    for factor in unit.symbol.split("*"):
        u, _, power = factor.partition("^")
        num, _, den = u.partition("/")
        num = DISPLAY_TO_SI.get(num, num)
        den = DISPLAY_TO_SI.get(den, den)
        parts.append(num + power + (f"_per_{den}" if den else ""))
    return re.sub(r"[^A-Za-z0-9_]+", "_", "_".join(parts)).strip("_")


def in_display(value, kind: str, spec: str = ".4g") -> str:
    """``value`` (SI) in the display unit of ``kind``, formatted with ``spec``: '205.000 mm'."""
    u = UNIT_KINDS[kind]
    return f"{value * u.factor:{spec}} {u.display}"


def format_pose(coordinates, angular, X, spec: str = ".6g") -> str:
    """``x=10 mm, alpha=5 deg``: task coordinates ``X`` (SI) named by ``coordinates``, those in
    ``angular`` as angles, the others as lengths, each formatted with ``spec``."""
    return ", ".join(f"{c}={in_display(v, 'angle' if c in angular else 'length', spec)}"
                     for c, v in zip(coordinates, X))


class QuantityError(ValueError):
    """A value without a required unit, with the wrong dimension, or unparsable."""


# "<number> <unit>" in the commonest units, converted without pint (importing pint and
# building its registry takes about half a second at every start): {unit: (kind, factor to
# SI)}. The factors reproduce pint's conversions exactly (tests/common/test_units.py compares them);
# anything else -- other units, prefixes, compound units, "nan", errors -- goes to pint.
_FAST_UNITS = {**{u: v for u, v in LITERAL_UNITS.items() if u not in ("um", "µm")}, **_OTHER_PLAIN_UNITS}
_FAST = re.compile(r"\s*(-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z]+)\s*")
_PLAIN = re.compile(r"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*")


def _fast_quantity(value: str, kind: str, field: str = "value"):
    """SI magnitude of ``value`` when it is a plain number and one unit of ``kind`` in
    :data:`_FAST_UNITS` (:class:`QuantityError`, as pint's path, for a unit there of another
    dimension), else None (pint decides)."""
    m = _FAST.fullmatch(value)
    if m is None:
        if _PLAIN.fullmatch(value) is None:
            return None
        # a plain number (pint reads it unitless): dimensionless, else the error of a missing unit
        if kind == "dimensionless":
            return float(value)
        if kind == "angle":
            raise QuantityError(f"{field}: {value!r} has no unit; give an angle such as '15 deg' or '0.2 rad'")
        raise QuantityError(f"{field}: {value!r} has no unit; give a {kind} such as '10 {DISPLAY_UNITS[kind]}'")
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
    si, dim = UNIT_KINDS[kind][:2]
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
    v = ureg.Quantity(value_si, UNIT_KINDS[kind].si).to(unit).magnitude
    return f"{v:.{digits}g} {unit}"
