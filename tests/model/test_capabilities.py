"""Every leg type of the registry through every part: each part works for a leg type that
declares the capability and refuses, by name and with the capability's name, one that does not;
and the declarations match what the parts do."""

import functools

import numpy as np
import pytest

import parasynth
from parasynth.model.spatial import rot_axis
from parasynth.engine.closure import plan
from parasynth.engine.core import HAVE_NUMBA
from parasynth.engine.indices import _Unsupported, coverage
from parasynth.export import ExportError, build_tree
from parasynth.measures.accuracy import closure_residuals
from parasynth.measures.dynamics import InertiaModel, LegInertia, PlatformInertia, RigidBody, inverse_dynamics
from parasynth.measures.stiffness import stiffness_matrix
from parasynth.model.legs import (CAPABILITIES, LEG_TYPES, UPS, LegCapabilities, LegCapabilityError, capabilities_of,
                                  supports, types_with)

#: A shipped mechanism holding each leg type (with its index there).
SHIPPED = {"SPS": "2rpu_2sps", "UPS": "gough_stewart_6ups", "PUS": "hexapod_6pus", "RPS": "3rps",
           "RPU": "2rpu_2sps", "UPU": "5pus_upu", "PRS": "3prs", "RUS": "hexapod_6rus"}


#: The chain limbs (model/chains.py, no shipped model): a structure of the vocabulary holding each.
CHAIN_STRUCTURES = {"RPUR": ("3T2R", 5), "PRUR": ("3T2R", 5), "SPU": ("3T3R", 6), "RRPS": ("3T3R", 6),
                    "RRUR": ("3T2R", 5), "RUU": ("3T0R", 3), "URPU": ("3T3R", 6), "PRRS": ("3T3R", 6)}


@functools.lru_cache(maxsize=None)
def _chain_mechanism(joints):
    motion, n = CHAIN_STRUCTURES[joints]
    found = parasynth.structures(motion, leg_types=[joints], legs=[n])
    return next(s for s in found if s.verified).mechanism()


def _with_leg(joints):
    if joints in CHAIN_STRUCTURES:
        mech = _chain_mechanism(joints)
        return mech, mech.legs[0]
    mech = parasynth.load_mechanism(SHIPPED[joints])
    leg = next(leg for leg in mech.legs if leg.joints == joints)
    return mech, leg


def test_every_registered_leg_type_is_covered_and_declares_every_capability():
    assert set(SHIPPED) | set(CHAIN_STRUCTURES) == set(LEG_TYPES)
    for name, cls in LEG_TYPES.items():
        caps = capabilities_of(cls)
        assert isinstance(caps, LegCapabilities)
        assert set(caps.__dataclass_fields__) == set(CAPABILITIES), name
        assert len(cls.constraint_rows) == sum(1 for _ in cls.constraint_rows if _ in ("length", "angle"))


def test_description_options_are_fields_of_the_leg_type():
    """What a description may give a leg (declared on the leg type) is what the class takes."""
    import dataclasses

    for name, cls in LEG_TYPES.items():
        fields = {f.name for f in dataclasses.fields(cls)}
        assert set(cls.description_options) <= fields, name
        assert set(cls.required_options) <= set(cls.description_options), name


@pytest.mark.parametrize("joints", sorted(LEG_TYPES))
def test_declared_constraint_rows_are_the_legs_constraint_wrenches(joints):
    """One closure row per constraint wrench the leg transmits (its twists' reciprocal screws)."""
    mech, leg = _with_leg(joints)
    p, R = mech.pose(np.asarray(mech.home, float)[None, :])
    st = leg.solve(p, R)
    W = leg.constraint_wrenches(st, p)
    assert W.shape[1] == len(leg.constraint_rows)
    T = leg.joint_twists(st, p)  # reciprocal: no power on any joint twist (w @ t = 0, model.spatial)
    if W.shape[1]:
        assert np.allclose(np.einsum("ncj,nkj->nck", W, T), 0.0, atol=1e-9)


def _refused(exc, leg, capability):
    msg = str(exc.value)
    assert f"leg {leg.name}" in msg and f"leg type {leg.joints}" in msg and repr(capability) in msg, msg


@pytest.mark.parametrize("joints", sorted(LEG_TYPES))
def test_accuracy_residuals_vanish_at_home_or_refuse(joints):
    mech, leg = _with_leg(joints)
    p, R = mech.pose(np.asarray(mech.home, float)[None, :])
    if not supports(leg, "accuracy"):
        with pytest.raises(LegCapabilityError) as e:
            closure_residuals(mech, p, R)
        _refused(e, leg, "accuracy")
        return
    r = closure_residuals(mech, p, R, legs=[leg])[0]
    # the actuator row against the leg's own inverse kinematics, the constraint rows zero
    assert len(r) == int(leg.is_actuated) + len(leg.constraint_rows)
    if leg.is_actuated:
        assert r[0] == pytest.approx(leg.solve(p, R).actuator[0], abs=1e-12)
    assert np.allclose(r[int(leg.is_actuated):], 0.0, atol=1e-9)
    # and off the constraint manifold (a pose moved along every coordinate) a constraint row moves
    if leg.constraint_rows:
        p2 = p + np.array([[0.013, -0.011, 0.007]])
        R2 = rot_axis(np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8]), 0.05) @ R
        r2 = closure_residuals(mech, p2, R2, legs=[leg])[0]
        assert np.max(np.abs(r2[int(leg.is_actuated):])) > 1e-4


def _inertia(mech):
    body = RigidBody(mass=1.0, inertia=(1e-3, 1e-3, 1e-4), offset=0.05)
    return InertiaModel(PlatformInertia(mass=2.0, inertia=(0.01, 0.01, 0.02)),
                        {leg.name: LegInertia(body, body) for leg in mech.legs})


@pytest.mark.parametrize("joints", sorted(LEG_TYPES))
def test_dynamics_works_or_refuses_by_name(joints):
    mech, leg = _with_leg(joints)
    X = np.asarray(mech.home, float)[None, :]
    zero = np.zeros_like(X)
    refusing = [lg for lg in mech.legs if not supports(lg, "dynamics")]
    if refusing:
        with pytest.raises(LegCapabilityError) as e:
            inverse_dynamics(mech, X, zero, zero, _inertia(mech), gravity=(0, 0, -9.81))
        _refused(e, refusing[0], "dynamics")
        assert isinstance(e.value, NotImplementedError)  # as the dynamics refused legs before
    else:
        tau = inverse_dynamics(mech, X, zero, zero, _inertia(mech), gravity=(0, 0, -9.81))
        assert np.all(tau.balanced) and np.all(np.isfinite(tau.actuator)) and np.any(tau.actuator != 0)  # gravity loads them
    if not supports(leg, "dynamics"):
        assert leg in refusing


@pytest.mark.parametrize("joints", sorted(LEG_TYPES))
def test_compiled_closure_stiffness_export_and_view_work_or_refuse(joints):
    mech, leg = _with_leg(joints)
    if HAVE_NUMBA:
        ok, why = coverage(mech)
        assert ok == all(supports(lg, "compiled") for lg in mech.legs), why
        if all(supports(lg, "closure") for lg in mech.legs):
            cp = plan([mech.legs])
            assert cp.m == mech.n_actuators + sum(len(lg.constraint_rows) for lg in mech.legs)
        else:
            with pytest.raises(_Unsupported) as e:
                plan([mech.legs])
            # a leg type without compiled kernels is refused for them first (a chain limb)
            word = "'closure'" if supports(leg, "compiled") else "'compiled'"
            assert word in str(e.value) and f"leg type {leg.joints}" in str(e.value)
    assert supports(leg, "stiffness")  # every leg type of the registry: checked by the call
    K = stiffness_matrix(mech, mech.home, diameter=0.02)
    assert K.shape == (6, 6) and np.allclose(K, K.T, rtol=1e-8, atol=1e-6 * np.max(np.abs(K)))
    if supports(leg, "export"):
        tree = build_tree(mech)
        assert tree is not None
    else:  # the chain limbs: refused by name
        with pytest.raises(ExportError) as e:
            build_tree(mech)
        _refused(e, leg, "export")


class CPS(UPS):
    """A leg class from elsewhere, with a cylindrical base joint: it declares nothing."""

    joints = "CPS"


def _with_cps():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    leg = mech.legs[0]
    mech.legs = (CPS(leg.name, leg.base, leg.platform, leg.base_ref, leg.platform_ref, leg.u_axis),) + mech.legs[1:]
    return mech, mech.legs[0]


def test_an_undeclared_leg_type_is_refused_by_name_by_every_part():
    mech, leg = _with_cps()
    assert capabilities_of(leg).names() == ()  # a subclass that renames its joints inherits nothing
    assert "CPS" not in types_with("export")
    X = np.asarray(mech.home, float)[None, :]
    p, R = mech.pose(X)
    with pytest.raises(LegCapabilityError) as e:
        closure_residuals(mech, p, R)
    _refused(e, leg, "accuracy")
    with pytest.raises(LegCapabilityError) as e:
        inverse_dynamics(mech, X, np.zeros_like(X), np.zeros_like(X), _inertia(mech))
    _refused(e, leg, "dynamics")
    with pytest.raises(LegCapabilityError) as e:
        stiffness_matrix(mech, mech.home)
    _refused(e, leg, "stiffness")
    with pytest.raises(ExportError) as e:
        build_tree(mech)
    _refused(e, leg, "export")
    if HAVE_NUMBA:
        ok, why = coverage(mech)
        assert not ok and "'compiled'" in why and "leg type CPS" in why
        with pytest.raises(_Unsupported, match="leg type CPS does not support '(compiled|closure)'"):
            plan([mech.legs])


def test_unknown_capability_is_refused():
    with pytest.raises(ValueError, match="unknown leg capability 'teleport'; allowed: compiled"):
        supports(UPS, "teleport")


def test_parts_hold_no_list_of_leg_types():
    """The leg type names appear in the leg declarations only (model/legs.py), not in the parts."""
    import pathlib
    import re

    src = pathlib.Path(parasynth.__file__).parent
    parts = ["measures/accuracy.py", "measures/dynamics.py", "measures/stiffness.py", "measures/robustness.py",
             "export/tree.py", "engine/closure.py", "report/interactive.py"]
    for f in parts:
        text = (src / f).read_text()
        hits = re.findall(r'"(?:%s)"' % "|".join(LEG_TYPES), text)
        assert not hits, (f, hits)
