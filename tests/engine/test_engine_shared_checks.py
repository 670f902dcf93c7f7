"""Designs that share their constraint values share the constraint objects and the kernels'
check tables (``parasynth.engine.core.leg_tables``): the shared tables must be those a fresh
computation gives, follow a changed bound, and never be shared where they depend on the legs'
geometry or on the mechanism object (expression constraints)."""

from __future__ import annotations

import numpy as np
import pytest

from parasynth import load_mechanism
from parasynth.engine import core

pytestmark = pytest.mark.skipif(not core.HAVE_NUMBA, reason="the check tables are the compiled engine's")


def _fresh_tables(mech):
    """The check tables computed without the memo (the function the memo keeps)."""
    legs = list(mech.legs)
    names = [leg.name for leg in legs]
    index = {n: i for i, n in enumerate(names)}
    act = np.array([1 if leg.is_actuated else 0 for leg in legs], dtype=np.int64)
    tables, exprs, rows = core._check_tables(mech, legs, list(mech.constraints.values()), None, act, index, names)
    return tables


def _tables(mech):
    return core.leg_tables(mech, list(mech.constraints.values()))[3]


def _assert_same(a, b):
    assert set(a) == set(b)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_designs_with_the_same_bounds_share_constraints_and_tables():
    a = load_mechanism("5pus_upu", link_length=0.20)
    b = load_mechanism("5pus_upu", link_length=0.21)  # the geometry differs, the bounds do not
    for name in a.constraints:
        assert a.constraints[name] is b.constraints[name], name
    ta, tb = _tables(a), _tables(b)
    _assert_same(ta, _fresh_tables(a))
    _assert_same(tb, _fresh_tables(b))
    # the legs' geometry is not in the tables but in the leg arrays, which stay per design
    Fa = core.leg_tables(a, list(a.constraints.values()))[2]
    Fb = core.leg_tables(b, list(b.constraints.values()))[2]
    assert not np.array_equal(Fa, Fb)


def test_a_changed_bound_gives_its_own_constraint_and_tables():
    a = load_mechanism("5pus_upu")
    b = load_mechanism("5pus_upu", sphere_max=np.radians(20.0))
    assert a.constraints["sphere_limit"] is not b.constraints["sphere_limit"]
    assert a.constraints["stroke"] is b.constraints["stroke"]
    ta, tb = _tables(a), _tables(b)
    assert not np.array_equal(ta["cone"], tb["cone"])
    _assert_same(tb, _fresh_tables(b))
    # and the compiled answer follows the bound: the NumPy reference agrees pose by pose
    rng = np.random.default_rng(3)
    X = b.home + rng.uniform(-1, 1, size=(4000, b.n_task)) * np.array([0.1, 0.1, 0.1, 0.4, 0.4])[:b.n_task]
    np.testing.assert_array_equal(b.is_feasible(X), b.is_feasible(X, engine="numpy"))
    assert (a.is_feasible(X) != b.is_feasible(X)).any()  # the tighter cone removes poses


def test_a_signed_zero_bound_is_its_own_constraint():
    from parasynth.mechanisms.description.constraints import _exact
    assert _exact(0.0) != _exact(-0.0)
    assert _exact(0.25) == _exact(0.25) and _exact(None) is None


def test_expression_constraints_are_built_per_mechanism():
    from parasynth.mechanisms.description import description_class
    import yaml
    from pathlib import Path
    import parasynth.mechanisms as M
    data = yaml.safe_load((Path(M.__file__).parent / "5pus_upu.yaml").read_text())
    data["name"] = "pus_expr_shared_check"
    data["constraints"] = list(data["constraints"]) + [
        {"name": "above_floor", "type": "expression", "margin": "pz + 0.4", "unit": "m"}]
    cls = description_class(data)
    a, b = cls(), cls(cls.Params(link_length=0.21))
    assert a.constraints["above_floor"] is not b.constraints["above_floor"]
    assert a.constraints["stroke"] is b.constraints["stroke"]
    X = a.home + np.array([0.0, 0.0, -0.5, 0.0, 0.0])[:a.n_task]
    for m in (a, b):
        _assert_same(_tables(m), _fresh_tables(m))
        assert not m.is_feasible(X) and not m.is_feasible(X, engine="numpy")
