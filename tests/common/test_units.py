"""Quantities: the pint-free fast path for "<number> <unit>" gives exactly what pint gives."""

import random

import pytest

from parasynth.common import units


def _pint_si(value: str, kind: str) -> float:
    si = units.UNIT_KINDS[kind].si
    q = units._ureg().Quantity(value)
    v = float(q.to(si).magnitude)
    return v if kind == "angle" else float(f"{v:.15g}")


def test_fast_units_agree_with_pint():
    rng = random.Random(7)
    numbers = ["0", "15", "205", "-20", "0.5", ".25", "12.", "1e-3", "2.5E2", "360", "-179.5"]
    numbers += [f"{rng.uniform(-500, 500):.{rng.randint(1, 9)}g}" for _ in range(400)]
    for unit, (kind, _) in units._FAST_UNITS.items():
        for x in numbers:
            for text in (f"{x} {unit}", f"{x}{unit}", f"  {x}   {unit} "):
                assert units._fast_quantity(text, kind) is not None, text
                assert units.parse_quantity(text, kind) == _pint_si(text.strip(), kind), text


@pytest.mark.parametrize("text,kind", [("15 deg", "dimensionless"), ("nan mm", "length"), ("inf deg", "angle"),
                                       ("1_000 mm", "length"), ("+5 mm", "length"), ("5 km", "length"),
                                       ("5 mm/s", "length"), ("0.2 m*m", "length")])
def test_other_forms_go_to_pint(text, kind):
    assert units._fast_quantity(text, kind) is None


def test_errors_unchanged():
    with pytest.raises(units.QuantityError, match="is not an angle"):
        units.parse_quantity("205 mm", "angle")
    with pytest.raises(units.QuantityError, match="not a finite length"):
        units.parse_quantity("nan mm", "length")
    with pytest.raises(units.QuantityError, match="bare number"):
        units.parse_quantity(5.0, "length")


def test_plain_numbers_agree_with_pint():
    """A number without a unit is read without pint: its value as a dimensionless number, and for
    any other kind the error pint's path gives (the parameter kind inference tries every kind)."""
    for text in ("1", "0", "15", " -2.5 ", "+5", ".25", "12.", "1e-3", "2.5E2"):
        for kind in units.UNIT_KINDS:
            real = units._fast_quantity
            try:
                units._fast_quantity = lambda *a, **k: None
                try:
                    slow = units.parse_quantity(text, kind, field="f")
                except units.QuantityError as e:
                    slow = str(e)
            finally:
                units._fast_quantity = real
            try:
                fast = units.parse_quantity(text, kind, field="f")
            except units.QuantityError as e:
                fast = str(e)
            assert fast == slow, (text, kind)


def test_wrong_dimension_errors_are_pints():
    """A fast-path unit of another dimension gives the error message pint's path gives."""
    for text, kind in [("205 mm", "angle"), ("15 deg", "length"), ("3 GPa", "length"), ("5 N", "pressure"),
                       ("2 kg", "stiffness"), ("1 s", "force")]:
        with pytest.raises(units.QuantityError) as fast:
            units.parse_quantity(text, kind, field="f")
        real = units._fast_quantity
        try:
            units._fast_quantity = lambda *a, **k: None
            with pytest.raises(units.QuantityError) as slow:
                units.parse_quantity(text, kind, field="f")
        finally:
            units._fast_quantity = real
        assert str(fast.value) == str(slow.value)
    assert units.parse_quantity("15 deg", "dimensionless") == pytest.approx(0.2617993877991494)
