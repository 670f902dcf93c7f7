"""Legs of a description: the order of named legs (actuator k drives the leg named L<k>),
mirrored crank pairs, and the actuator range of crank angles (docs/mechanisms.md, legs)."""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest
import yaml

from parasynth.mechanisms.description import DescriptionError, description_class
from parasynth.model.mechanism import EngineFallbackWarning

pytestmark = pytest.mark.filterwarnings("ignore::parasynth.model.mechanism.EngineFallbackWarning")

#: A 6-RUS hexapod with mirrored crank pairs on radial axes: the first leg of each base pair
#: turns about the radial direction, the second about its negative (docs/mechanisms.md), so it
#: takes two entries, named to keep the legs numbered around the base.
MIRRORED = yaml.safe_load("""
name: mirrored_6rus
parameters:
  base_radius: 300 mm
  platform_radius: 150 mm
  height: 400 mm
  link_length: 350 mm
  crank_length: 120 mm
base:
  B: {pattern: paired, n: 3, radius: base_radius, phase: 0 deg, separation: 20 deg}
platform:
  A: {pattern: paired, n: 3, radius: platform_radius, phase: 60 deg, separation: 20 deg}
legs:
  - {type: RUS, base: "B[0, 2, 4]", platform: "A[5, 1, 3]", r_axis: radial, crank_length: crank_length,
     link_length: link_length, actuated: R, names: [L1, L3, L5]}
  - {type: RUS, base: "B[1, 3, 5]", platform: "A[0, 2, 4]", r_axis: -radial, crank_length: crank_length,
     link_length: link_length, actuated: R, names: [L2, L4, L6]}
task:
  coordinates: {x: length, y: length, z: length, alpha: angle, beta: angle, gamma: angle}
  position: [x, y, z]
  orientation: {convention: xyz, angles: [alpha, beta, gamma]}
  home: {x: 0 mm, y: 0 mm, z: height, alpha: 0 deg, beta: 0 deg, gamma: 0 deg}
length_scale: base_radius
constraints:
  - {name: crank_range, type: actuator_range, min: -120 deg, max: 10 deg}
""")

#: Poses without any symmetry (x, y, z in m; alpha, beta, gamma in rad).
POSES = np.array([[0.005, 0.010, 0.370, 0.02, 0.01, 0.03],
                  [-0.012, 0.004, 0.390, -0.03, 0.02, -0.01],
                  [0.0, -0.015, 0.360, 0.01, -0.025, 0.04]])


def _mech(data):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        return description_class(data)()


def _rot(a, b, g):
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    Rz = np.array([[cg, -sg, 0], [sg, cg, 0], [0, 0, 1]])
    return Rx @ Ry @ Rz


def _paired(radius, phase_deg, k):
    """The k-th point of a paired pattern (n = 3, separation 20 deg), by hand."""
    ang = np.radians(phase_deg + 120 * (k // 2) + (-10 if k % 2 == 0 else 10))
    return radius * np.array([np.cos(ang), np.sin(ang), 0.0]), ang


def _closure_residual(X, k, t):
    """|S - C(t)| - link length for leg L<k> (1-based) of MIRRORED at pose X and crank angle t,
    all by hand: the leg's base anchor B[k-1], its platform anchor, its crank axis +-radial and
    the crank zero r_axis x z."""
    B, phi = _paired(0.3, 0.0, k - 1)
    plat_index = [5, 0, 1, 2, 3, 4][k - 1]
    A, _ = _paired(0.15, 60.0, plat_index)
    S = X[:3] + _rot(*X[3:]) @ A
    radial = np.array([np.cos(phi), np.sin(phi), 0.0])
    a = radial if k % 2 == 1 else -radial
    c0 = np.cross(a, [0.0, 0.0, 1.0])
    C = B + 0.12 * (np.cos(t) * c0 + np.sin(t) * np.cross(a, c0))
    return np.linalg.norm(S - C) - 0.35


def test_actuator_k_drives_the_leg_named_Lk():
    """The description names its legs L1, L3, L5 in its first entry and L2, L4, L6 in its
    second; the mechanism's legs are L1 .. L6, and actuator t<k> is the crank angle that closes
    the loop of leg L<k> (checked by hand, not against another description), at poses where the
    legs' crank angles all differ."""
    mech = _mech(MIRRORED)
    assert [leg.name for leg in mech.legs] == ["L1", "L2", "L3", "L4", "L5", "L6"]
    assert mech.actuators == ("t1", "t2", "t3", "t4", "t5", "t6")
    for X in POSES:
        t = mech.inverse_kinematics(X).actuators
        assert np.all(np.isfinite(t)) and np.min(np.abs(np.diff(np.sort(t)))) > 1e-4
        for k in range(1, 7):
            assert abs(_closure_residual(X, k, t[k - 1])) < 1e-12, (k, X)
            # ... and not the crank angle of any other leg
            assert all(abs(_closure_residual(X, k, t[j])) > 1e-6 for j in range(6) if j != k - 1)


def test_the_order_is_that_of_the_description_for_other_names():
    d = copy.deepcopy(MIRRORED)
    d["legs"][0]["names"] = ["a1", "a3", "a5"]
    d["legs"][1]["names"] = ["a2", "a4", "a6"]
    mech = _mech(d)
    assert [leg.name for leg in mech.legs] == ["a1", "a3", "a5", "a2", "a4", "a6"]
    t = mech.inverse_kinematics(POSES[0]).actuators
    for pos, k in enumerate([1, 3, 5, 2, 4, 6]):  # actuator t<pos+1> is the leg at that position
        assert abs(_closure_residual(POSES[0], k, t[pos])) < 1e-12
    # numbers that are not 1..n keep the description's order too
    d["legs"][0]["names"] = ["L0", "L2", "L4"]
    d["legs"][1]["names"] = ["L1", "L3", "L5"]
    assert [leg.name for leg in _mech(d).legs] == ["L0", "L2", "L4", "L1", "L3", "L5"]


def test_named_legs_reordered_keep_their_constraints_and_stiffness_by_name():
    """Constraints and stiffness entries name legs: the reordering keeps each with its leg."""
    d = copy.deepcopy(MIRRORED)
    d["constraints"] = [{"name": "pair", "type": "interference", "diameter": "10 mm", "pairs": [["L1", "L2"]]}]
    d["stiffness"] = [{"legs": ["L2"], "actuator": "1e5 N/m"}, {"legs": ["L1", "L3", "L4", "L5", "L6"],
                                                                    "actuator": "2e5 N/m"}]
    mech = _mech(d)
    assert mech.declared_stiffness["L2"]["actuator"] == 1e5
    assert mech.declared_stiffness["L3"]["actuator"] == 2e5
    X = POSES[0]
    assert np.isfinite(mech.constraint_margins(X, engine="numpy")["pair"])


def _mirror(X):
    """The pose mirrored across the base's xz plane (y -> -y): R -> M R M gives alpha -> -alpha,
    beta -> beta, gamma -> -gamma for the xyz convention."""
    return X * np.array([1, -1, 1, -1, 1, -1])


#: Legs swapped by the mirror across the xz plane: base pairs (0, 1), (2, 5), (3, 4).
MIRROR_OF = {1: 2, 2: 1, 3: 6, 6: 3, 4: 5, 5: 4}


@pytest.mark.parametrize("layout", ["radial, two entries", "tangent, one entry"])
def test_mirrored_crank_pairs_have_equal_angles_at_mirrored_poses(layout):
    d = copy.deepcopy(MIRRORED)
    if layout.startswith("tangent"):
        d["legs"] = [{"type": "RUS", "base": "B", "platform": "A[5, 0, 1, 2, 3, 4]", "r_axis": "tangent",
                      "crank_length": "crank_length", "link_length": "link_length", "actuated": "R"}]
        d["constraints"] = []
    mech = _mech(d)
    for X in POSES:
        t, tm = mech.inverse_kinematics(X).actuators, mech.inverse_kinematics(_mirror(X)).actuators
        assert np.all(np.isfinite(t))
        for k, j in MIRROR_OF.items():
            assert tm[k - 1] == pytest.approx(t[j - 1], abs=1e-12), (k, j)
    home = mech.inverse_kinematics(mech.home).actuators
    np.testing.assert_allclose(home, home[0], atol=1e-12)  # one crank angle at the symmetric home


def test_a_crank_actuator_range_is_an_angle_range():
    mech = _mech(MIRRORED)
    c = mech.constraints["crank_range"]
    assert c.unit == "rad" and (c.lo, c.hi) == (pytest.approx(np.radians(-120)), pytest.approx(np.radians(10)))
    X = POSES
    t = np.stack([mech.inverse_kinematics(x).actuators for x in X])
    want = np.min(np.minimum(t - np.radians(-120), np.radians(10) - t), axis=1)
    np.testing.assert_allclose(mech.constraint_margins(X, engine="numpy")["crank_range"], want, atol=1e-12)


def _crank_error(minimum, maximum="10 deg", data=MIRRORED) -> str:
    d = copy.deepcopy(data)
    d["parameters"]["reach"] = "50 mm"
    d["constraints"][0].update(min=minimum, max=maximum)
    with pytest.raises(DescriptionError) as e:
        _mech(d)
    assert "\n" not in str(e.value)
    return str(e.value)


def test_crank_actuator_ranges_of_the_wrong_kind_are_refused():
    assert "crank_range).min: '-120 mm' is not an angle" in _crank_error("-120 mm")
    msg = _crank_error("-reach")
    assert "crank_range).min: parameters.reach is a length" in msg and "crank angles" in msg
    msg = _crank_error("-200 deg")
    assert "crank_range).min: a crank angle range lies within [-180 deg, 180 deg]" in msg and "-200 deg" in msg
    mixed = copy.deepcopy(MIRRORED)
    mixed["legs"][1] = {"type": "SPS", "base": "B[1, 3, 5]", "platform": "A[0, 2, 4]", "names": ["L2", "L4", "L6"]}
    msg = _crank_error("-120 deg", data=mixed)
    assert "mirrored_6rus: constraints[0] (crank_range): an actuator_range applies to every actuator" in msg
    assert "leg_length" in msg
