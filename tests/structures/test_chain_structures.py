"""Structures of chain limbs (model/chains.py): structures("3T2R") holds the 5-RPUR and 5-PRUR of
Masouleh, Gosselin et al., structures("3T3R") the 6-SPU and 6-RRPS; their finite motion checked
on the limbs' own inverse kinematics, and the parts that do not support a chain limb refuse it."""

import warnings

import numpy as np
import pytest

import parasynth
from parasynth.model.chains import ChainError, ChainLeg, register_chain
from parasynth.model.legs import LegCapabilityError, require
from parasynth.model.mechanism import EngineFallbackWarning
from parasynth.model.spatial import euler_to_matrix, rot_x, rot_y
from parasynth.structures import StructureError

from _enumerated import enumerated, motion_group


@pytest.fixture(scope="module")
def found_3t2r():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        return enumerated("3T2R")


@motion_group("3T2R")
def test_default_3t2r_holds_5_rpur_and_5_prur(found_3t2r):
    names = {s.name for s in found_3t2r}
    assert {"5-RPUR", "5-PRUR"} <= names
    for s in found_3t2r:
        if s.name in ("5-RPUR", "5-PRUR"):
            assert s.verified and s.template == "xy_ring" and s.motion == "3T2R"
            assert s.axes == {"translations": ("x", "y", "z"), "rotations": ("x", "moving y")}
    # the regular pentagon is singular at home (as the 5-x/UPU): listed, not kept
    assert {"5-RPUR", "5-PRUR"} <= set(found_3t2r.dropped_names["singular at home"])


@motion_group("3T2R")
@pytest.mark.parametrize("name", ["5-RPUR", "5-PRUR"])
def test_finite_motion_is_x_y_z_and_rotations_about_x_and_moving_y(found_3t2r, name):
    """On the limbs' numerical inverse kinematics (not the template): every limb reaches poses
    R = Rx(alpha) Ry(beta) anywhere in the central box, and none of them reaches the same poses
    turned about the moving z."""
    s = next(s for s in found_3t2r if s.name == name)
    m = s.mechanism()
    rng = np.random.default_rng(5)
    n = 20
    p = np.array([0.0, 0.0, m.params.height]) + rng.uniform(-0.03, 0.03, (n, 3))
    a, b = rng.uniform(-0.15, 0.15, (2, n))
    R = rot_x(a) @ rot_y(b)
    Rg = R @ euler_to_matrix("xyz", np.stack([np.zeros(n), np.zeros(n), np.full(n, 0.05)], -1))
    for leg in m.legs:
        assert isinstance(leg, ChainLeg)
        assert leg.solve(p, R).reachable.all(), leg.name
    # a rotation about the moving z is forbidden by every limb's constraint couple
    assert not any(leg.solve(p, Rg).reachable.any() for leg in m.legs)


def test_3t3r_holds_6_spu_and_6_rrps():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        found = parasynth.structures("3T3R", leg_types=["SPU", "RRPS"], legs=[6])
    names = [s.name for s in found]
    assert names.count("6-SPU") == 2 and names.count("6-RRPS") == 2  # paired and irregular
    assert all(s.verified for s in found)


@motion_group("3T2R")
def test_parts_refuse_a_chain_limb_by_name(found_3t2r):
    m = next(s for s in found_3t2r if s.name == "5-RPUR").mechanism()
    for cap in ("closure", "dynamics", "accuracy", "export", "view"):
        with pytest.raises(LegCapabilityError, match=rf"leg L1: leg type RPUR does not support '{cap}'"):
            require(m.legs[0], cap)
    require(m.legs[0], "compiled")
    with warnings.catch_warnings():  # feasibility and the indices: compiled (engine/chains.py, engine/indices.py)
        warnings.simplefilter("error", EngineFallbackWarning)
        assert m.is_feasible(np.atleast_2d(m.home))[0]
        got = m.singularity_margin(np.atleast_2d(m.home))
    np.testing.assert_allclose(got, m.singularity_margin(np.atleast_2d(m.home), engine="numpy"), rtol=0, atol=1e-9)


def test_register_chain_keeps_the_closed_forms():
    with pytest.raises(ChainError, match="UPS is a hand-written leg type already"):
        register_chain("UP*S")


def test_a_motion_the_limb_types_cannot_produce_is_refused_in_one_line():
    with pytest.raises(StructureError) as e:
        parasynth.structures("3T3R", leg_types=["RPUR", "PRUR"])
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("motion 3T3R: the limb types RPUR, PRUR leave at most 5 freedoms")
    assert "allowed: a motion of at most 5 freedoms" in msg
