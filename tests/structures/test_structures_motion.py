"""Structures whose motion is computed from their limbs (structures/motion.py): the 1T2R rings
against the shipped 3-RPS and 3-PRS, Tsai's translational 3-UPU, 3T1R, the reasons of the
remaining "no task rule" drops, and every enumerated structure's mobility recomputed by a
screw-theory rank computation written here (joint twists built from the limbs' geometry, not by
the leg models or the enumerator)."""

import functools

import numpy as np
import pytest

from parasynth import load_mechanism
from parasynth.model.chains import ChainLeg
from parasynth.model.legs import LEG_TYPES

CHAIN_TYPES = tuple(k for k, v in LEG_TYPES.items() if issubclass(v, ChainLeg))
from parasynth.structures import structures
from parasynth.model.spatial import euler_to_matrix
from parasynth.structures.motion import (HOME_OFFSET_MAX, HOME_TILT_MAX, NoHome, NoTaskRule, candidate_rule,
                                         home_is_near, motion_rule)

from _enumerated import enumerated, motion_group, per_motion
from _support import engine_fallbacks


_found = enumerated


def _by_name(found, name):
    out = [s for s in found if s.name == name]
    assert out, f"{name} not in {[s.name for s in found]}"
    return out[0]


# -- the independent screw-theory mobility -------------------------------------------------------
def _unit(v):
    return v / np.linalg.norm(v)


def _perp_pair(n):
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _unit(np.cross(n, a))
    return e1, np.cross(n, e1)


def _rev(axis, point):
    """Unit twist (v at the origin, omega) of a rotation about ``axis`` through ``point``."""
    a = _unit(np.asarray(axis, float))
    return np.concatenate([np.cross(point, a), a])  # v_O = a x (O - r) = r x a


def _pri(axis):
    return np.concatenate([_unit(np.asarray(axis, float)), np.zeros(3)])


def _leg_twists(leg, st, k, R):
    """The joint twists of one limb at pose k, and the index of its actuated joint (None when
    passive), from the limb's joint axes and the joint centres of its inverse kinematics."""
    B, A, n = st.base_point[k], st.platform_point[k], st.direction[k]
    j = leg.joints
    sph = [_rev(e, A) for e in np.eye(3)]
    act = None
    if j == "SPS":
        tw = [_rev(e, B) for e in np.eye(3)] + [_pri(n)] + sph
        act = 3
    elif j in ("UPS", "UPU"):
        a1 = leg.u_axis
        tw = [_rev(a1, B), _rev(np.cross(a1, n), B), _pri(n)]
        if j == "UPS":
            tw += sph
        else:
            a4 = R @ leg.u_platform_axis
            tw += [_rev(np.cross(a4, n), A), _rev(a4, A)]
        act = 2
    elif j == "PUS":
        a1 = leg.u_axis
        tw = [_pri(leg.slider_axis), _rev(a1, B), _rev(np.cross(a1, n), B)] + sph
        act = 0
    elif j == "RUS":
        e1, e2 = _perp_pair(n)
        tw = [_rev(leg.r_axis, leg.base), _rev(e1, B), _rev(e2, B)] + sph
        act = 0
    elif j == "RPS":
        tw = [_rev(leg.r_axis, B), _pri(n)] + sph
        act = 1
    elif j == "PRS":
        tw = [_pri(leg.slider_axis), _rev(leg.r_axis, B)] + sph
        act = 0
    elif j == "RPU":
        tw = [_rev(leg.r_axis, B), _pri(n), _rev(leg.r_axis, A), _rev(R @ leg.u_platform_axis, A)]
        act = 1
    elif isinstance(leg, ChainLeg):
        # a limb from a joint string: its twists by finite differences of its forward kinematics
        # at the solved joint coordinates (not by its twist formula), taken at the origin
        q = st.extra["q"][k:k + 1]
        pos, Rc, _, _ = leg.forward(q)
        tw, h = [], 1e-6
        for m in range(q.shape[1]):
            dq = np.zeros_like(q)
            dq[0, m] = h
            (pp, Rp, _, _), (pm, Rm, _, _) = leg.forward(q + dq), leg.forward(q - dq)
            v = (pp - pm)[0] / (2 * h)
            Wd = ((Rp - Rm)[0] / (2 * h)) @ Rc[0].T
            w = np.array([Wd[2, 1], Wd[0, 2], Wd[1, 0]])
            tw.append(np.concatenate([v + np.cross(w, -pos[0]), w]))  # v at the origin
        act = leg.spec.actuated if leg.spec.actuated is None else leg._joint_of.index(leg.spec.actuated)
    else:  # pragma: no cover
        raise AssertionError(f"no twists written for {j}")
    return np.array(tw), (act if leg.is_actuated else None)


def _reciprocal(T, L):
    """Wrenches (f, m at the origin) with f.v + m.omega = 0 for every twist row of T, scaled by
    the length L so that the rank threshold is dimensionless."""
    if not len(T):
        return np.eye(6)
    Ts = T * np.r_[np.ones(3), np.full(3, L)]
    _, s, Vt = np.linalg.svd(Ts)
    r = int(np.sum(s > 1e-9 * s[0]))
    return Vt[r:]  # in (f, m / L) scaled coordinates


def _independent_mobility(mech, X):
    """(motion type, controlled) at pose X by screw theory."""
    L = mech.length_scale
    ik = mech.inverse_kinematics(X[None])
    assert ik.reachable[0]
    _, R = mech._pose(X[None])
    R = R[0]
    cons, act_cons = [], []
    for leg, st in zip(mech.legs, ik.legs):
        T, a = _leg_twists(leg, st, 0, R)
        cons.append(_reciprocal(T, L))
        act_cons.append(_reciprocal(np.delete(T, a, axis=0) if a is not None else T, L))
    W = np.vstack(cons)
    s = np.linalg.svd(W, compute_uv=False) if len(W) else np.zeros(0)
    r = int(np.sum(s > 1e-8 * max(s[0], 1e-300))) if len(s) else 0
    # freedoms: twists reciprocal to all constraint wrenches (W . (v, omega L) = 0)
    _, s2, Vt = np.linalg.svd(np.vstack([W, np.zeros((1, 6))]))
    free = Vt[r:]  # (6 - r, 6) in (v, omega L)
    n_rot = int(np.sum(np.linalg.svd(free[:, 3:], compute_uv=False) > 1e-8)) if len(free) else 0
    Wa = np.vstack(act_cons)
    sa = np.linalg.svd(Wa, compute_uv=False)
    controlled = int(np.sum(sa > 1e-8 * sa[0])) == 6
    return f"{6 - r - n_rot}T{n_rot}R", controlled


@pytest.mark.parametrize("motion, all_axes", per_motion([(m, False) for m in ("1T2R", "3T0R", "0T3R", "3T1R", "2T2R",
                                                                              "3T2R", "3T3R")]
                                                      + [(m, True) for m in ("1T2R", "3T0R", "3T1R")]))
def test_every_structure_mobility_independently(motion, all_axes):
    """Every enumerated structure of ``motion``: at home and at three random reachable poses of the
    central half of its task box the motion type recomputed here is ``motion``, and the actuators control it at one of them
    at least. (Away from home the central UPU's constraint of the 5-x/UPU is a screw of non-zero
    pitch, read instantaneously as 2T3R, docs/structures.md: there the number of freedoms is
    checked.)"""
    found = _found(motion, all_axes)
    assert len(found)
    rng = np.random.default_rng(11)
    for s in found:
        m = s.mechanism()
        lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
        poses = []
        for _ in range(200):
            X = m.home + 0.25 * (hi - lo) * rng.uniform(-1, 1, len(lo))
            if m.inverse_kinematics(X[None]).reachable[0]:
                poses.append(X)
            if len(poses) == 3:
                break
        assert len(poses) == 3, s.name
        res = [_independent_mobility(m, X) for X in [m.home] + poses]
        assert res[0][0] == motion, (s.name, s.arrangement, res)
        dof = sum(int(motion[k]) for k in (0, 2))
        for t, _ in res[1:]:
            assert (t == motion) if s.template != "upu_central" else (int(t[0]) + int(t[2]) == dof), \
                (s.name, s.arrangement, res)
        assert any(c for _, c in res), (s.name, res)


def test_independent_mobility_detects_a_wrong_motion():
    """The test's own computation reads the shipped 3-RPS as 1T2R and the Gough-Stewart as 3T3R
    (so that it can disagree with a structure)."""
    m = load_mechanism("3rps")
    assert _independent_mobility(m, m.home)[0] == "1T2R"
    g = load_mechanism("gough_stewart_6ups")
    assert _independent_mobility(g, g.home) == ("3T3R", True)


# -- 1T2R: the shipped 3-RPS and 3-PRS -------------------------------------------------------------
@motion_group("1T2R")
@pytest.mark.parametrize("name, shipped", [("3-RPS", "3rps"), ("3-PRS", "3prs")])
def test_1t2r_rings_match_the_shipped_models(name, shipped):
    """structures("1T2R") gives the 3-RPS and 3-PRS; with the shipped model's radii and no
    platform twist, their parasitic x, y and gamma at random (z, alpha, beta) equal the shipped
    descriptions' closed forms to 1e-9."""
    s = _by_name(_found("1T2R"), name)
    ref = load_mechanism(shipped)
    assert s.mechanism_class().task_coordinates == ("z", "alpha", "beta") == ref.task_coordinates
    m = s.mechanism(base_radius=ref.params.base_radius, platform_radius=ref.params.platform_radius,
                    platform_twist=0.0)
    rng = np.random.default_rng(4)
    lo, hi = (np.array(v) for v in zip(*[ref.default_ranges()[k] for k in ref.task_coordinates]))
    X = lo + (hi - lo) * rng.uniform(0.1, 0.9, (50, 3))
    p0, R0 = ref._pose(X)
    p1, R1 = m._pose(X)
    assert np.all(np.isfinite(p1))
    assert np.max(np.abs(p1 - p0)) < 1e-9 and np.max(np.abs(R1 - R0)) < 1e-9
    assert s.motion == "1T2R" and s.template == "solved"


# -- 3T0R and 3T1R -------------------------------------------------------------------------------
@motion_group("3T0R")
def test_3t0r_tsai_3upu_translates():
    """Tsai's 3-UPU (universal-joint axes tangential at both ends, cross axes parallel): the
    platform keeps its orientation (the one at home) at random poses of the task box."""
    s = _by_name(_found("3T0R"), "3-UPU")
    assert dict(s.groups[0].axes) == {"u_axis": "tangent", "u_platform_axis": "tangent"}
    m = s.mechanism()
    rng = np.random.default_rng(2)
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    X = lo + (hi - lo) * rng.uniform(0.1, 0.9, (30, 3))
    _, R = m._pose(X)
    _, R0 = m._pose(m.home[None])
    ok = np.all(np.isfinite(R), axis=(1, 2))
    assert ok.mean() > 0.9
    assert np.max(np.abs(R[ok] - R0[0])) < 1e-9


@motion_group("1T2R")
def test_3upu_axes_distinguish_translation_from_rotation():
    """With every axis choice the 3-UPU rings split by motion: tangent/tangent translates (3T0R),
    radial base or platform axes with a vertical one at the other end rotate (1T2R, with
    parasitic motion), vertical axes at both ends add the rotation about z (3T1R with 4 limbs)."""
    t0 = {tuple(v for _, v in s.groups[0].axes) for s in _found("3T0R", True) if s.name == "3-UPU"}
    r2 = {tuple(v for _, v in s.groups[0].axes) for s in _found("1T2R", True) if s.name == "3-UPU"}
    assert ("tangent", "tangent") in t0 and not t0 & r2
    assert ("z", "radial") in r2 or ("radial", "z") in r2


@motion_group("3T1R")
def test_3t1r_gives_upu_structures():
    names = {s.name for s in _found("3T1R")}
    assert any("UPU" in n for n in names), names


# -- the drops -----------------------------------------------------------------------------------
@pytest.mark.parametrize("motion", per_motion(("1T2R", "3T2R", "2T2R", "3T0R")))
def test_no_task_rule_is_rare_and_says_why(motion):
    """Chain limbs have closure equations (model/chains.py): no candidate is dropped for want of
    them, and the drops left are a few, each with its reason."""
    for motion in (motion,):
        f = _found(motion)
        assert not [k for k, v in f.no_task_rule.items() if v.startswith("no closure equations")]
        assert f.dropped["no task rule"] <= 12
        assert f.dropped["no task rule"] == len(f.no_task_rule)
        assert all(isinstance(v, str) and v for v in f.no_task_rule.values())
        # --show-dropped says why of each, under the reason's line, in words (no markup)
        lines = f.dropped_lines()
        for name, why in f.no_task_rule.items():
            assert f"  {name}: {why}" in lines
        assert not [x for x in lines if "``" in x]


@motion_group("3T0R")
def test_chain_limbs_in_solved_structures():
    """Structures of chain limbs whose motion no template gives are solved on the chains' closure
    equations: the 3-RUU (3T0R) among them, and chain limbs with a central constraining limb."""
    solved = [s for s in _found("3T0R") if s.template == "solved"
              and any(g.limb in CHAIN_TYPES for g in s.groups)]
    assert {"3-RUU", "3-RUU/UPU"} <= {s.name for s in solved}


def test_motion_rule_of_chain_limbs_solves_on_numpy_and_agrees_with_the_compiled_closure(monkeypatch):
    """A rule solves one pose at a time on the NumPy reference, chain limbs too: the compiled
    chain closure is not called (nor compiled on an empty cache); the same rule computed with the
    compiled closure equations (the engine's entry point forced back to them) has the same
    motion, the same dependent coordinates and their home values equal to 1e-9."""
    from parasynth import engine
    from parasynth.engine import chains
    from parasynth.structures import motion
    from parasynth.structures.synthesis import Group, _Candidate, _description
    from parasynth.structures.vocabulary import TEMPLATES

    c = _Candidate((Group("RUU", 3, True, "regular", ()),))
    desc = _description(c, TEMPLATES["free"], "t")
    calls = []
    orig = chains._closure_kernel
    monkeypatch.setattr(chains, "_closure_kernel", lambda *a: (calls.append(1), orig(*a))[1])
    rule = motion_rule(desc)
    assert not calls
    assert rule.name == "solved" and rule.motion == "3T0R", rule
    real = engine.closure_residuals

    class Forced:  # the module's `engine` with its closure equations compiled whatever it asks
        def __getattr__(self, name):
            return getattr(engine, name)

        @staticmethod
        def closure_residuals(legs, p, R, L, engine="compiled"):
            return real(legs, p, R, L)

    monkeypatch.setattr(motion, "engine", Forced())
    compiled = motion_rule(desc)
    if engine.core.HAVE_NUMBA:
        assert calls  # the forced rule did run the compiled closure
    assert (compiled.motion, compiled.dependent, compiled.independent) == (rule.motion, rule.dependent,
                                                                           rule.independent)
    a = [float(v.split()[0]) for v in rule.task["solve"]["start"].values()]
    b = [float(v.split()[0]) for v in compiled.task["solve"]["start"].values()]
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)


def test_motion_rule_refuses_with_a_reason():
    from parasynth.structures.synthesis import Group, _Candidate, _description
    from parasynth.structures.vocabulary import TEMPLATES
    # a 3-RPS ring turns the platform by -platform_twist, a central UPU with its axes along y
    # keeps it from turning: no assembly near home
    c = _Candidate((Group("RPS", 3, True, "regular", (("r_axis", "tangent"),)),
                    Group("UPU", 1, False, "central", (("u_axis", "y"), ("u_platform_axis", "y")))))
    with pytest.raises(NoTaskRule, match="no solution near the nominal home"):
        motion_rule(_description(c, TEMPLATES["free"], "t"))
    c = _Candidate((Group("SPS", 6, True, "paired", ()),))
    with pytest.raises(NoTaskRule, match="no limb has closure equations"):
        motion_rule(_description(c, TEMPLATES["free"], "t"))


def test_home_is_near_reads_tilt_and_offset_not_the_turn_about_the_vertical():
    """A level pose turned about the vertical by any angle is near; a tilt beyond HOME_TILT_MAX
    about any horizontal axis, or a centre a length scale away, is not (each said in words)."""
    V0 = np.array([0.0, 0.0, 0.4, 0.0, 0.0, 0.0])
    for g in (0.0, 1.0, np.pi):
        assert home_is_near(np.array([0, 0, 0.4, 0, 0, g]), V0, 0.3) is None
    t = HOME_TILT_MAX + 0.02
    # a tilt about the horizontal axis at 45 deg, written as two Euler angles: R[2, 2] = cos t
    a = np.arctan(np.tan(t) * np.sqrt(0.5))
    b = np.arcsin(np.sin(t) * np.sqrt(0.5))
    assert abs(euler_to_matrix("xyz", np.array([[a, b, 0.3]]))[0][2, 2] - np.cos(t)) < 1e-12
    assert f"tilted {np.degrees(t):.0f} deg" in home_is_near(np.array([0, 0, 0.4, a, b, 0.3]), V0, 0.3)
    assert home_is_near(np.array([0, 0, 0.4, 0.7 * HOME_TILT_MAX, 0.7 * HOME_TILT_MAX, 0]), V0, 0.3) is None
    L = 0.3
    off = (HOME_OFFSET_MAX + 0.01) * L
    assert "off the vertical" in home_is_near(np.array([off * 0.6, off * 0.8, 0.4, 0, 0, 0]), V0, L)
    assert "its height" in home_is_near(np.array([0, 0, 0.4 - off, 0, 0, 0]), V0, L)
    assert home_is_near(np.array([0.99 * L, 0, 0.4 + 0.99 * L, 0, 0, 0]), V0, L) is None


def _tilt_and_offset(m):
    p, R = m._pose(m.home[None])
    return np.arccos(np.clip(R[0][2, 2], -1, 1)), np.hypot(p[0][0], p[0][1])


@pytest.mark.parametrize("motion", per_motion(["1T2R", "3T0R", "3T1R"]))
def test_solved_structures_have_a_home_near_the_nominal_one(motion):
    """Every structure whose motion is computed from its limbs (every axis choice) is posed at
    home with the platform at most HOME_TILT_MAX from level and its centre within a length scale
    (base_radius) of the vertical, as its limbs assemble there (the pose read from the
    mechanism's own pose map); and the 1T2R and 3T0R structures share their motion's task
    coordinates (z, alpha, beta; x, y, z; a study over them needs that: a 3-UPU assembled on its
    side, with x, y and alpha as coordinates, failed the shipped structures_1t2r). The rotation of
    a 3T1R is about x or about the moving y as the limbs' axes give it."""
    found = _found(motion, True)
    coords = {s.mechanism_class().task_coordinates for s in found}
    if motion != "3T1R":
        assert coords == {{"1T2R": ("z", "alpha", "beta"), "3T0R": ("x", "y", "z")}[motion]}, coords
    for s in found:
        if s.template != "solved":
            continue
        m = s.mechanism()
        tilt, off = _tilt_and_offset(m)
        assert tilt <= HOME_TILT_MAX + 1e-9 and off <= HOME_OFFSET_MAX * m.params.base_radius, (s.name, s.arrangement)
        assert m.inverse_kinematics(m.home[None]).reachable[0], (s.name, s.arrangement)


@motion_group("1T2R")
def test_a_candidate_assembled_far_from_home_is_dropped_as_no_home():
    """The 3-UPU with tangential base and vertical platform axes: its closure's minimum-norm
    solve from the level home ends (where it converges) with the platform on its side; that is
    no home, and the candidate is dropped as "no home" with the reason, whatever the solve's last
    bits do on this machine."""
    from parasynth.structures.synthesis import Group, _Candidate, _description
    from parasynth.structures.vocabulary import TEMPLATES
    g = (Group("UPU", 3, True, "regular", (("u_axis", "tangent"), ("u_platform_axis", "z"))),)
    with pytest.raises(NoHome, match="no solution near the nominal home|give a home far from the nominal one"):
        motion_rule(_description(_Candidate(g), TEMPLATES["free"], "t"))
    rule, why, drop = candidate_rule(g, lambda t: _description(_Candidate(g), t, "t"))
    assert rule is None and drop == "no home" and "nominal home" in why
    f = _found("1T2R", True)
    assert any(k.startswith("3-UPU [3 actuated UPU regular (u_axis=tangent,u_platform_axis=z)") for k in f.no_home), \
        f.no_home
    assert f.dropped["no home"] == len(f.no_home) and not f.dropped["no task rule"]
    assert "no home (" in "\n".join(f.dropped_lines())


@pytest.mark.parametrize("motion", per_motion(["1T2R", "3T0R", "0T3R", "3T1R"]))
def test_solved_structures_run_compiled_and_agree_with_numpy(motion):
    """Feasibility, margins and the singularity margin of every solved structure on the compiled
    engine (the unrolled solve, no fallback) equal the NumPy reference over its task box."""
    import warnings

    from parasynth import engine
    from parasynth.model.mechanism import EngineFallbackWarning

    for s in _found(motion):
        if s.template != "solved":
            continue
        m = s.mechanism()
        lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
        X = lo + (hi - lo) * np.random.default_rng(5).uniform(0, 1, (400, len(lo)))
        if any(g.limb in CHAIN_TYPES for g in s.groups):
            # chain limbs: feasibility by the compiled chain solve (engine/chains.py) and the
            # singularity margin by the index kernels (their rows from that solve), no fallback,
            # equal to NumPy
            X = X[:60]
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", EngineFallbackWarning)
                fc = m.is_feasible(X)
                sc = m.singularity_margin(X)
            assert not engine_fallbacks(m, caught), s.name
            assert np.array_equal(fc, m.is_feasible(X, engine="numpy")), s.name
            sn = m.singularity_margin(X, engine="numpy")
            both = np.isfinite(sn)
            assert np.array_equal(both, np.isfinite(sc)) and np.allclose(sc[both], sn[both], atol=1e-9), s.name
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("error", EngineFallbackWarning)
            fc = m.is_feasible(X)
            sc = m.singularity_margin(X)
            v, _, _, T = engine.pose_batch(m, X, twist=True)
        T0 = m._twist_map(X[v])
        assert np.max(np.abs(T[v] - T0)) < 1e-8 * max(1.0, np.max(np.abs(T0))), s.name
        assert np.array_equal(fc, m.is_feasible(X, engine="numpy")), s.name
        sn = m.singularity_margin(X, engine="numpy")
        both = np.isfinite(sn)
        assert np.array_equal(both, np.isfinite(sc)) and np.allclose(sc[both], sn[both], atol=1e-9), s.name


@motion_group("1T2R")
def test_structure_yaml_round_trip(tmp_path):
    """The written description of a solved structure loads (load_mechanism) with the same motion."""
    s = _by_name(_found("1T2R"), "3-RPS")
    path = s.write(tmp_path)
    m = load_mechanism(str(path))
    X = m.home + np.array([0.05, 0.2, -0.1])
    p0, R0 = s.mechanism()._pose(X[None])
    p1, R1 = m._pose(X[None])
    assert np.allclose(p0, p1, atol=1e-12) and np.allclose(R0, R1, atol=1e-12)
    assert "solve" in s.description["task"]


@motion_group("1T2R")
def test_forward_kinematics_of_a_solved_structure_inverts_its_inverse_kinematics():
    s = _by_name(_found("1T2R"), "3-PRS")
    m = s.mechanism()
    X = m.home + np.array([0.02, 0.12, -0.08])
    q = m.inverse_kinematics(X[None]).actuators[0]
    assert np.allclose(m.forward_kinematics(q), X, atol=1e-9)


@motion_group("3T0R")
def test_zero_length_upu_not_valid_in_either_engine_so_the_3upu_upu_runs_compiled():
    """A UPU limb of zero length (its platform anchor on its base joint) has no direction: the
    NumPy closure and the compiled pose program both find such a pose not valid. The 3T0R
    3-UPU/UPU of all_axes has that at the zero pose, one of the compiled program's probe poses:
    it runs compiled (no fallback) and agrees with NumPy."""
    import warnings

    from parasynth import engine
    from parasynth.model.mechanism import EngineFallbackWarning

    s = next(x for x in enumerated("3T0R", True) if x.label == "3-UPU/UPU")
    m = s.mechanism()
    zero = np.zeros(m.n_task)
    assert m.pose_valid(np.array([m.home, zero])).tolist() == [True, False]
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    X = lo + (hi - lo) * np.random.default_rng(3).uniform(0, 1, (400, len(lo)))
    with warnings.catch_warnings():
        warnings.simplefilter("error", EngineFallbackWarning)
        v, p, R, _ = engine.pose_batch(m, np.array([m.home, zero]))
        fc = m.is_feasible(X)
        mc = m.constraint_margins(X)
    assert v.tolist() == [True, False]
    p0, R0 = m.pose(m.home[None])
    np.testing.assert_allclose(p[0], p0[0], atol=1e-12)
    assert np.array_equal(fc, m.is_feasible(X, engine="numpy"))
    mn = m.constraint_margins(X, engine="numpy")
    for k in mn:
        fin = np.isfinite(mn[k])
        assert np.array_equal(fin, np.isfinite(mc[k])), k
        np.testing.assert_allclose(mc[k][fin], mn[k][fin], rtol=0, atol=1e-9, err_msg=k)
