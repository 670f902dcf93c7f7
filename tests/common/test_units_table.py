"""The one units table (parasynth.common.units.UNIT_KINDS): its factors agree with pint, every other
table of units is derived from it, and no other module of src/ writes one of its own."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pint
import pytest

from parasynth.measures import display
from parasynth.common import units
from parasynth.mechanisms.description import expressions, parameters
from parasynth.mechanisms.description.expressions import Expression
from parasynth.common.units import DISPLAY_TO_SI, DISPLAY_UNITS, LITERAL_UNITS, SI_UNIT_KINDS, UNIT_KINDS

SRC = Path(units.__file__).resolve().parents[1]
UREG = pint.UnitRegistry()


@pytest.mark.parametrize("kind", sorted(UNIT_KINDS))
def test_display_factor_is_pints_conversion(kind):
    u = UNIT_KINDS[kind]
    si = UREG.Quantity(1.0, u.si)
    # the SI unit has the declared dimensionality (angles and pure numbers: none)
    assert si.dimensionality == UREG.get_dimensionality(u.dimensionality)
    assert UREG.Quantity(1.0, u.display).dimensionality == si.dimensionality
    assert si.to(u.display).magnitude == pytest.approx(u.factor, rel=1e-14)
    # and a value in SI comes back from its display value
    assert UREG.Quantity(0.205 * u.factor, u.display).to(u.si).magnitude == pytest.approx(0.205, rel=1e-14)


@pytest.mark.parametrize("unit", sorted(LITERAL_UNITS))
def test_expression_unit_factor_is_pints_conversion(unit):
    kind, factor = LITERAL_UNITS[unit]
    assert UREG.Quantity(1.0, unit).to(UNIT_KINDS[kind].si).magnitude == pytest.approx(factor, rel=1e-14)


def test_literal_and_display_factors_agree():
    # the display unit of a length and of an angle is also an expression literal, with the inverse factor
    for kind in ("length", "angle"):
        u = UNIT_KINDS[kind]
        assert LITERAL_UNITS[u.display][0] == kind
        assert LITERAL_UNITS[u.display][1] * u.factor == pytest.approx(1.0, rel=1e-15)
        assert LITERAL_UNITS[u.si] == (kind, 1.0)


def test_parse_quantity_matches_the_table_for_every_kind():
    for kind, u in UNIT_KINDS.items():
        if kind == "dimensionless":
            assert units.parse_quantity(3, kind) == 3.0
            continue
        text = f"2.5 {u.display}"
        assert units.parse_quantity(text, kind) == pytest.approx(2.5 / u.factor, rel=1e-14), kind
        assert units.format_quantity(2.5 / u.factor, kind) == f"2.5 {u.display}"


def test_previous_tables_are_unchanged():
    """The tables the modules wrote themselves before the single table, as they were."""
    old_units = {"length": ("mm", 1e3), "angle": ("deg", 180.0 / math.pi), "area": ("cm^2", 1e4),
                 "volume": ("cm^3", 1e6), "force": ("N", 1.0), "stiffness": ("N/m", 1.0),
                 "rotational_stiffness": ("N*m/rad", 1.0), "pressure": ("GPa", 1e-9), "torque": ("N*m", 1.0),
                 "mass": ("kg", 1.0), "time": ("s", 1.0), "dimensionless": ("", 1.0)}
    # the kinds added since (actuator speeds and power, for units that follow the actuators)
    new_units = {"speed": ("m/s", 1.0), "angular_speed": ("rad/s", 1.0), "power": ("W", 1.0)}
    assert {k: (u.symbol, u.factor) for k, u in display.UNITS.items()} == {**old_units, **new_units}
    old_si_kind = {"m": "length", "rad": "angle", "m^2": "area", "m^3": "volume", "N": "force", "N/m": "stiffness",
                   "N*m": "torque", "N m": "torque", "Nm": "torque", "kg": "mass", "s": "time", "1": "dimensionless",
                   "": "dimensionless"}
    for si, kind in old_si_kind.items():
        assert SI_UNIT_KINDS[si] == kind
        assert display.unit_for_si(si) == display.UNITS[kind]
    assert display.unit_for_si("mixed") == display.NONE
    assert display.unit_for_si("N/m (translational)") == display.Unit("N/m (translational)", 1.0)
    assert expressions.UNIT_FACTORS == {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6,
                                        "deg": math.pi / 180.0, "rad": 1.0}
    assert DISPLAY_TO_SI == {"mm": "m", "cm": "m", "deg": "rad", "GPa": "Pa"}
    assert DISPLAY_UNITS == {"length": "mm", "angle": "deg", "area": "cm^2", "volume": "cm^3", "force": "N",
                             "stiffness": "N/m", "rotational_stiffness": "N*m/rad", "pressure": "GPa",
                             "torque": "N*m", "mass": "kg", "time": "s",
                             **{k: u for k, (u, _) in new_units.items()}}
    assert parameters._EXAMPLE_UNIT == {"length": "mm", "angle": "deg", "stiffness": "N/m",
                                        "rotational_stiffness": "N*m/rad", "pressure": "GPa"}
    assert parameters._SI_UNIT == {"length": "m", "angle": "rad", "stiffness": "N/m",
                                   "rotational_stiffness": "N*m/rad", "pressure": "Pa",
                                   "dimensionless": "a plain number"}


@pytest.mark.parametrize("n_length, n_angle, symbol, factor", [
    (0, 0, "", 1.0), (1, 0, "mm", 1e3), (2, 0, "cm^2", 1e4), (3, 0, "cm^3", 1e6), (4, 0, "m^4", 1.0),
    (0, 1, "deg", 180 / math.pi), (3, 2, "cm^3*deg^2", 1e6 * (180 / math.pi) ** 2),
    (1, 4, "mm*deg^4", 1e3 * (180 / math.pi) ** 4)])
def test_compound_unit(n_length, n_angle, symbol, factor):
    u = units.compound_unit(n_length, n_angle)
    assert u.symbol == symbol
    assert u.factor == pytest.approx(factor, rel=1e-15)
    if symbol and not symbol.startswith("m^"):  # pint agrees on the product's factor
        si = "*".join(["m"] * n_length + ["rad"] * n_angle)
        assert UREG.Quantity(1.0, si).to(symbol).magnitude == pytest.approx(factor, rel=1e-12)


def test_expression_literals_give_the_same_si_values():
    # previous output: float(number) * factor, exactly
    assert Expression("205 mm", "p")({}) == 205 * 1e-3
    assert Expression("1.5 cm + 3 um", "p")({}) == 1.5 * 1e-2 + 3 * 1e-6
    assert Expression("15 deg", "p")({}) == 15 * (math.pi / 180.0)
    assert Expression("2 µm", "p")({}) == 2 * 1e-6
    assert Expression("0.5 rad + 1 m", "p")({}) == 1.5
    assert Expression("2*mm_x", "p").names == {"mm_x"}  # a name starting with a unit is a name


def test_derived_tables_are_the_units_table():
    # the column suffix of each display unit names its SI unit (the one units layer does both)
    assert units.column_suffix(units.UNITS["length"]) == "m"
    assert units.column_suffix(units.UNITS["angle"]) == "rad"
    assert units.column_suffix(units.UNITS["volume"]) == "m3"
    assert units.column_suffix(units.compound_unit(3, 2)) == "m3_rad2"
    assert units.column_suffix(units.UNITS["stiffness"]) == "N_per_m"
    assert units.column_suffix(units.UNITS["pressure"]) == "Pa"
    assert units.column_suffix(units.NONE) == ""
    assert units.si_compound(("m", "m", "m", "rad", "rad")) == "m^3 rad^2"
    assert units.si_compound(("rad", "m")) == "m rad" and units.si_compound(()) == "1"
    assert units.format_pose(("x", "alpha"), {"alpha"}, (0.205, math.radians(15.0)), ".4g") == "x=205 mm, alpha=15 deg"
    assert units.in_display(0.205, "length", ".3f") == "205.000 mm"
    for kind, u in UNIT_KINDS.items():
        assert display.UNITS[kind].symbol == u.display and display.UNITS[kind].factor == u.factor
        assert SI_UNIT_KINDS[u.si] == kind
    assert expressions.UNIT_FACTORS == {k: f for k, (_, f) in LITERAL_UNITS.items()}


# A table of units written out: a unit spelling as a key or value of a mapping, or a conversion
# factor between SI and a display unit.
_TABLE = re.compile(r"""["'](?:mm|cm|um|deg|rad|GPa|cm\^[23]|m\^[23])["']\s*:|:\s*["'](?:mm|deg|cm\^[23]|GPa)["']"""
                    r"""|\*\s*1e3\b|/\s*1e3\b|180(?:\.0)?\s*/\s*(?:math|np)\.pi"""
                    r"""|(?:math|np)\.pi\s*/\s*180|\brad2deg\b|\bdeg2rad\b|\bnp\.degrees\b|\bmath\.degrees\b"""
                    r"""|\bmath\.radians\b""")
#: Modules other projects are changing now, that still convert to mm and deg themselves.
_NOT_YET: set = set()


def test_no_other_module_writes_a_units_table():
    offenders = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        if rel == "common/units.py" or rel in _NOT_YET:
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("#", 1)[0]
            if _TABLE.search(code):
                offenders.append(f"{rel}:{n}: {line.strip()}")
    assert not offenders, "units written outside parasynth/common/units.py:\n" + "\n".join(offenders)


def test_the_check_finds_a_table():
    # the pattern of the test above catches the tables this module replaced
    for line in ['UNIT_FACTORS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}', '_SI = {"mm": "m", "deg": "rad"}',
                 'unit = {"length": "mm", "angle": "deg"}', "x = v * 1e3", "a = 180.0 / math.pi",
                 'f"{np.rad2deg(v):.3f} deg"']:
        assert _TABLE.search(line), line
