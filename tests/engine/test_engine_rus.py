"""The RUS leg on the compiled engine against the NumPy reference.

RUS limbs (a crank about ``r_axis``, a universal joint at its tip, a link of fixed length, a
sphere on the platform) are compiled like the other leg types: feasibility, constraint
margins (crank-angle range, joint cone limits, link length, interference), the pose-wise
indices (singularity margin, transmission, condition number, leg directions) and the
constraint rank. The reference is the NumPy path of ``parasynth.model.legs.RUS`` (which
``tests/structures/test_structures.py`` checks against finite differences and reciprocity); the
contract is the engine's (``tests/engine/test_engine.py``): booleans equal away from the feasibility
boundary, margins to rounding, indices to 1e-9.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from parasynth import engine
from parasynth.model.constraints import ActuatorRange
from parasynth.engine import indices as ei
from parasynth.measures.indices import local_condition_number, transmission_indices
from parasynth.model.mechanism import EngineFallbackWarning
from parasynth.mechanisms.description import description_class
from test_engine import check_mechanism

pytestmark = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not importable: the NumPy path is the engine")

ATOL = 1e-9


def _rus(mixed: bool, r_axis: str = "tangent", branch: int = 1):
    """A 6-RUS (paired hexagons) or a 3-RUS&3-UPS with every constraint type a RUS leg has."""
    legs = [{"type": "RUS", "base": "B", "platform": "A[5, 0, 1, 2, 3, 4]" if not mixed else "A",
             "r_axis": r_axis, "crank_length": "h", "link_length": "L", "branch": branch, "actuated": "R"}]
    base = {"B": {"pattern": "paired", "n": 3, "radius": "b", "separation": "sep"}}
    plat = {"A": {"pattern": "paired", "n": 3, "radius": "a", "phase": "60 deg", "separation": "sep"}}
    names = [f"L{i}" for i in range(1, 7)]
    if mixed:
        base = {"B": {"pattern": "polygon", "n": 3, "radius": "b"},
                "C": {"pattern": "polygon", "n": 3, "radius": "b", "phase": "60 deg"}}
        plat = {"A": {"pattern": "polygon", "n": 3, "radius": "a", "phase": "20 deg"},
                "D": {"pattern": "polygon", "n": 3, "radius": "a", "phase": "80 deg"}}
        legs.append({"type": "UPS", "base": "C", "platform": "D", "u_axis": "radial", "actuated": "P"})
    cons = [
        {"name": "cone_u", "type": "joint_angle", "key": "U_base_cone", "max": "20 deg", "legs": names[:3]},
        {"name": "cone_s", "type": "joint_angle", "key": "S_platform_cone", "max": "35 deg"},
        {"name": "links", "type": "leg_length", "legs": names[:3], "min": "300 mm", "max": "400 mm"},
        {"name": "clash", "type": "interference", "diameter": "dia", "pairs": [["L1", "L2"], ["L1", "L4"]]},
    ]
    d = {
        "name": f"rus_{'mixed' if mixed else 'six'}_{r_axis}_{branch}",
        "parameters": {"b": "300 mm", "a": "150 mm", "h": "120 mm", "L": "350 mm", "sep": "20 deg", "dia": "0 mm"},
        "base": base, "platform": plat, "legs": legs,
        "task": {"coordinates": {"x": "length", "y": "length", "z": "length", "alpha": "angle", "beta": "angle",
                                 "gamma": "angle"},
                 "position": ["x", "y", "z"],
                 "orientation": {"convention": "xyz", "angles": ["alpha", "beta", "gamma"]},
                 "home": {"x": "0 mm", "y": "0 mm", "z": "400 mm" if branch == 1 else "250 mm", "alpha": "0 deg",
                          "beta": "0 deg", "gamma": "0 deg"},
                 "ranges": {"x": ["-60 mm", "60 mm"], "y": ["-60 mm", "60 mm"],
                            "z": ["340 mm", "460 mm"] if branch == 1 else ["190 mm", "310 mm"],
                            "alpha": ["-15 deg", "15 deg"], "beta": ["-15 deg", "15 deg"],
                            "gamma": ["-15 deg", "15 deg"]}},
        "length_scale": "b",
        "constraints": cons,
    }
    cls = description_class(d)
    mech = cls(cls.Params())
    # a link diameter that the closest of the two leg pairs violates at about a third of the poses
    X = np.random.default_rng(0).uniform(*(np.array(v) for v in zip(*mech.default_ranges().values())), (2000, 6))
    dist = mech.constraint_margins(X, engine="numpy")["clash"]
    mech = cls(cls.Params(dia=float(np.percentile(dist[np.isfinite(dist)], 30))))
    if not mixed:  # crank angles (the description language's actuator_range is a length range): 60
        # deg beyond the home angles, short of +-pi, where the angle wraps (a range across the wrap
        # has a margin that jumps there, decided by the last bit of the crank's sine)
        q0 = mech.inverse_kinematics(mech.home).actuators
        lo, hi = max(q0.min() - 1.05, 0.2 - np.pi), min(q0.max() + 1.05, np.pi - 0.2)
        mech._constraints = {**mech.constraints, "cranks": ActuatorRange("cranks", lo=lo, hi=hi)}
    return mech


CASES = [(False, "tangent", 1), (False, "radial", 1), (False, "tangent", -1), (True, "tangent", 1)]
IDS = [f"{'mixed' if m else '6-RUS'}-{a}-{b:+d}" for m, a, b in CASES]


@pytest.mark.parametrize("mixed,axis,branch", CASES, ids=IDS)
def test_feasibility_margins_and_poses_agree(mixed, axis, branch):
    mech = _rus(mixed, axis, branch)
    assert engine.available(mech), engine.reason(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("error", EngineFallbackWarning)  # no fallback anywhere
        ref = check_mechanism(mech, n=3000, seed=3)
    # the comparison saw both outcomes, and every constraint but the (constant) link length
    # bites somewhere
    assert 0.05 < ref.mean() < 0.95
    X = np.random.default_rng(3).uniform(*(np.array(v) for v in zip(*mech.default_ranges().values())), (3000, 6))
    M = mech.constraint_margins(X, engine="numpy")
    reach = np.isfinite(M["clash"])
    for name, m in M.items():
        if name == "links":
            np.testing.assert_allclose(m[reach], 0.05, rtol=0, atol=1e-15)  # min(350 - 300, 400 - 350) mm
            continue
        assert (m[reach] < 0).any() and (m[reach] >= 0).any(), name


@pytest.mark.parametrize("mixed,axis,branch", CASES, ids=IDS)
def test_indices_agree(mixed, axis, branch):
    mech = _rus(mixed, axis, branch)
    assert ei.coverage(mech) == (True, "")
    lo, hi = (np.array(v) for v in zip(*mech.default_ranges().values()))
    X = np.random.default_rng(5).uniform(lo, hi, (3000, 6))
    X = np.vstack([X, mech.home + 5.0])  # out of every link's reach
    with warnings.catch_warnings():
        warnings.simplefilter("error", EngineFallbackWarning)
        got = mech.singularity_margin(X)
        inp, out, lti = ei.transmission(mech, X)
        kappa = local_condition_number(mech, X)
        dirs, reach = ei.leg_directions(mech, X)
    ref = mech.singularity_margin(X, engine="numpy")
    assert np.isfinite(ref).sum() > 200 and np.isnan(ref[-1])
    np.testing.assert_allclose(got, ref, rtol=0, atol=ATOL, equal_nan=True)
    tr = transmission_indices(mech, X)  # the NumPy reference (the compiled form is ei.transmission)
    for a, b in ((tr.input, inp), (tr.output, out), (tr.lti, lti)):
        np.testing.assert_allclose(b, a, rtol=0, atol=ATOL, equal_nan=True)
    k0 = local_condition_number(mech, X, engine="numpy")
    np.testing.assert_array_equal(np.isinf(k0), np.isinf(kappa))
    np.testing.assert_allclose(kappa, k0, rtol=1e-9, equal_nan=True)
    ik = mech.inverse_kinematics(X)
    np.testing.assert_array_equal(reach, ik.reachable)
    _, states, _ = mech.leg_states(X[ik.reachable])
    np.testing.assert_allclose(dirs[ik.reachable], np.stack([st.direction for st in states], axis=1), atol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert ei.constraint_rank(mech) == mech.mobility().constraint_rank == 0


def test_crank_angles_are_the_actuators():
    """The compiled crank angle is the NumPy actuator (the margins of the crank range are
    linear in it, so they compare the angle itself)."""
    mech = _rus(False)
    X = mech.home + np.random.default_rng(8).uniform(-1, 1, (500, 6)) * [0.08, 0.08, 0.08, 0.3, 0.3, 0.3]
    ik = mech.inverse_kinematics(X)
    m = engine.margins(mech, X)["cranks"]
    q = ik.actuators[ik.reachable]
    c = mech.constraints["cranks"]
    expect = np.minimum(q - c.lo, c.hi - q).min(axis=1)
    np.testing.assert_allclose(m[ik.reachable], expect, rtol=0, atol=1e-12)
