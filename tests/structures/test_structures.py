"""Structural synthesis (parasynth.structures) and the RUS leg it added.

* the done-when cases of the structures issue: 6-UPS and 6-PUS for 3T3R, 5-PUS/UPU for 3T2R,
  2-RPU&2-SPS for 2T2R, each with the requested motion and every freedom controlled;
* every structure of the default vocabulary for 3T3R, 3T2R and 2T2R: its mechanism's mobility,
  its description round trip through YAML and ``load_mechanism``, and the compiled engine
  against the NumPy reference;
* duplicate removal checked with an independent graph-isomorphism test (networkx) on joint
  graphs built from the descriptions;
* the RUS leg against finite differences, reciprocity and a forward/inverse round trip;
* bad input and the command line.
"""

from __future__ import annotations

import io
import itertools
import warnings
from contextlib import redirect_stderr, redirect_stdout

import networkx as nx
import numpy as np
import pytest
import yaml

import parasynth
from parasynth.model.legs import supports
from parasynth import cli
from parasynth.model.chains import ChainLeg
from parasynth.model.legs import RUS
from parasynth.model.mechanism import EngineFallbackWarning
from parasynth.mechanisms import load_mechanism
from parasynth.mechanisms.description import DescriptionError, description_class
from parasynth.model.spatial import reciprocal_basis
from parasynth.structures import LIMB_TYPES, candidates, structures
from parasynth.structures.synthesis import _description, _key, _leg_types

from _enumerated import enumerated, per_motion
from _support import engine_fallbacks

MOTIONS = ("3T3R", "3T2R", "2T2R")




def _names(found):
    """The structures reported: their names and those of the equivalent ones reported with them."""
    return {s.name for s in found} | {n for s in found for n, _ in s.equivalents}


def _check_controlled_motion(s):
    m = s.mechanism()
    mob = m.mobility(warn=False)
    assert mob.type == s.motion, (s.name, mob.type)
    assert mob.dof == sum(int(c) for c in s.motion[::2])
    assert mob.controlled and mob.n_actuators == mob.dof, (s.name, mob.summary())
    # away from the (symmetric, possibly singular) home pose the actuators control every freedom
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    X = m.home + 0.2 * (hi - lo) * np.random.default_rng(3).uniform(-1, 1, (20, len(lo)))
    X = X[m.inverse_kinematics(X).reachable]
    assert len(X), s.name
    here = m.mobility(X[0], warn=False)
    assert here.dof == mob.dof and len(here.uncontrolled_twists) == 0, (s.name, here.summary())
    W = m.wrench_matrix(X[0])
    W[:, 3:] /= m.length_scale
    assert np.linalg.matrix_rank(W, tol=1e-8 * np.abs(W).max()) == 6


# -- the done-when cases -----------------------------------------------------------------------------
def test_3t3r_with_ups_and_pus_includes_6_ups_and_6_pus():
    found = parasynth.structures("3T3R", leg_types=["UPS", "PUS"])
    assert {"6-UPS", "6-PUS"} <= _names(found)
    for s in found:
        assert s.motion == "3T3R"
        assert sum(s.actuated_counts.values()) == 6
        _check_controlled_motion(s)


def test_3t2r_with_pus_and_upu_includes_5_pus_upu():
    found = parasynth.structures("3T2R", leg_types=["PUS", "UPU"])
    s = next(s for s in found if s.name == "5-PUS/UPU")
    assert isinstance(s, parasynth.Structure)
    assert s.leg_counts == {"PUS": 5, "UPU": 1}
    assert s.actuated_counts == {"PUS": 5}
    assert s.motion == "3T2R" and s.template == "upu_central"
    for s in found:
        _check_controlled_motion(s)
    # the constraint of the passive limb: one couple, about the base normal at the reference pose
    m = s.mechanism()
    mob = m.mobility(warn=False)
    assert mob.constraint_rank == 1
    leg = m.legs[-1]
    st = leg.solve(*[a[None] for a in m.pose(m.home)])
    C = reciprocal_basis(leg.joint_twists(st, m.pose(m.home)[0][None]), m.length_scale)[0]
    assert np.allclose(C[0, :3], 0, atol=1e-12)
    assert abs(abs(C[0, 5]) - np.linalg.norm(C[0, 3:])) < 1e-9


def test_2t2r_with_rpu_and_sps_includes_2_rpu_2_sps():
    found = parasynth.structures("2T2R", leg_types=["RPU", "SPS"])
    s = next(s for s in found if s.name == "2-RPU&2-SPS")
    assert s.leg_counts == {"RPU": 2, "SPS": 2} and s.actuated_counts == {"RPU": 2, "SPS": 2}
    assert s.axes == {"translations": ("x", "z"), "rotations": ("y", "moving x")}
    for s in found:
        _check_controlled_motion(s)
    # the same freedoms as the shipped 2-RPU&2-SPS with x a free coordinate
    ref = load_mechanism("2rpu_2sps", coupled=False)
    assert ref.mobility(warn=False).type == s.mechanism().mobility(warn=False).type == "2T2R"


# -- every structure of the default vocabulary ---------------------------------------------------------
@pytest.mark.parametrize("motion", per_motion(MOTIONS))
def test_default_vocabulary_structures_are_verified_and_load_from_yaml(motion, tmp_path):
    found = enumerated(motion)
    assert len(found) >= 3
    assert found.enumerated == len(candidates(list(LIMB_TYPES)))
    assert sum(found.dropped.values()) + len(found) == found.enumerated
    assert found.dropped["duplicate"] > 0
    for s in found:
        assert s.motion == motion
        _check_controlled_motion(s)
        # the description written to YAML loads and gives the same mechanism
        path = s.write(tmp_path)
        m1, m2 = s.mechanism(), load_mechanism(str(path))
        X = m1.home + np.random.default_rng(0).normal(0, 0.01, (16, m1.n_task))
        a1, a2 = m1.inverse_kinematics(X).actuators, m2.inverse_kinematics(X).actuators
        assert np.allclose(a1, a2, equal_nan=True) and np.isfinite(a1).any()
        assert yaml.safe_load(path.read_text()) == s.description


@pytest.mark.parametrize("motion", per_motion(MOTIONS))
def test_engine_agrees_with_numpy_on_every_structure(motion):
    counts = []
    for s in enumerated(motion):
        m = s.mechanism()
        lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
        # 2000 poses over 1.5 times the task box; for a structure of chain limbs (their NumPy
        # reference, with a parasitic motion solved on the chains' closure equations, costs up to
        # ~25 ms a pose) 200 of them and 50 around its home pose (the box's corners are often
        # beyond their reach); where the motion itself is solved on a chain limb's closure (both
        # engines pose it by the NumPy solve, ~20 ms a pose) 30 and 10
        rng = np.random.default_rng(1)
        chained = any(isinstance(lg, ChainLeg) for lg in m.legs)  # solved numerically: fewer poses
        on_chains = any(isinstance(lg, ChainLeg) for lg in getattr(m, "_solve_legs", ()))
        n_box, n_home = (30, 10) if on_chains else (200, 50) if chained else (2000, 0)
        X = (lo + hi) / 2 + 1.5 * (hi - lo) * rng.uniform(-0.5, 0.5, size=(n_box, len(lo)))
        if n_home:
            X = np.vstack([m.home + 0.05 * (hi - lo) * rng.uniform(-0.5, 0.5, size=(n_home, len(lo))), X])
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            fc = m.is_feasible(X)
            mc = m.constraint_margins(X)
        fallbacks = [x for x in w if issubclass(x.category, EngineFallbackWarning)]
        chain = [lg for lg in m.legs if not supports(lg, "compiled")]
        # every structure runs on the compiled engine: the hand-written limbs, RUS limbs included,
        # on the kernels; a chain limb (model/chains.py) by its compiled inverse kinematics
        # (engine/chains.py), the other legs and the constraints as the NumPy reference
        feas = [x for x in fallbacks if "is_feasible/constraint_margins" in str(x.message)]
        assert not feas, (s.name, [str(x.message) for x in feas])
        if not chain:
            assert not engine_fallbacks(m, w), (s.name, engine_fallbacks(m, w))
        fn = m.is_feasible(X, engine="numpy")
        mn = m.constraint_margins(X, engine="numpy")
        near = np.zeros(len(X), bool)
        for k in mn:
            fin = np.isfinite(mn[k])
            assert np.array_equal(fin, np.isfinite(mc[k])), (s.name, k)
            assert np.allclose(mc[k][fin], mn[k][fin], atol=1e-12, rtol=1e-9), (s.name, k)
            near |= fin & (np.abs(mn[k]) < 1e-12)
        assert np.array_equal(fc[~near], fn[~near]), s.name
        assert fn.sum() > 0, s.name
        counts.append(fn.mean())
        if chain:  # no compiled pose-wise indices for a chain limb (it declares no 'compiled')
            continue
        # the compiled pose-wise indices too (singularity margin, to 1e-9 as tests/engine/test_engine_indices.py)
        Xr = X[m.inverse_kinematics(X).reachable][:200]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", EngineFallbackWarning)
            sm = m.singularity_margin(Xr)
        assert not engine_fallbacks(m, caught), (s.name, engine_fallbacks(m, caught))
        np.testing.assert_allclose(sm, m.singularity_margin(Xr, engine="numpy"), rtol=0, atol=1e-9, err_msg=s.name)
    assert min(counts) < 1.0  # the comparison saw infeasible poses too


# -- duplicates: an independent isomorphism test ---------------------------------------------------------
def _joint_graph(desc: dict) -> nx.MultiGraph:
    """Bodies as nodes (base, platform, the links of each limb), joints as labelled edges: the
    joint letter, whether it is actuated, and for the joint at the base the limb's anchor
    pattern and joint-axis options, read from the description alone."""
    g = nx.MultiGraph()
    g.add_node("base", kind="base")
    g.add_node("platform", kind="platform")
    for i, leg in enumerate(desc["legs"]):
        t = leg["type"]
        ref = leg["base"]
        if isinstance(ref, list):
            where, count = "centre", 1
        else:
            name, _, idx = ref.partition("[")  # "B1" (the whole set) or "B1[2]" (one limb of it)
            pat = desc["base"][name]
            where = pat["pattern"]
            if where == "circle":  # explicit angles: which shared parameters space them
                words = str(pat["angles"])
                where = ("circle", "separation" in words, "offset" in words)
                count = len(pat["angles"])
            else:
                count = pat["n"] * (2 if where == "paired" else 1)
            if idx:
                count = len(idx.rstrip("]").split(","))
        # an explicit direction written per limb (a universal joint's axis through the centre, set by
        # the limb's anchor angle) is a property of the anchor, not a label of its own: a ring turned
        # by a phase writes other numbers for the same joint
        opts = tuple(sorted((k, "per-limb direction" if isinstance(v, list) else str(v)) for k, v in leg.items()
                            if k not in ("type", "base", "platform", "actuated")))
        act = leg.get("actuated", "none")
        for k in range(count):  # one chain of bodies per limb of the entry
            bodies = ["base"] + [f"{i}.{k}.{j}" for j in range(len(t) - 1)] + ["platform"]
            for b in bodies[1:-1]:
                g.add_node(b, kind="link")
            for j, letter in enumerate(t):
                actuated = act != "none" and letter == act and t.index(act) == j
                label = (letter, actuated) + ((where, opts) if j == 0 else ())
                g.add_edge(bodies[j], bodies[j + 1], label=label)
    return g


def _iso(a, b) -> bool:
    return nx.is_isomorphic(a, b, node_match=lambda x, y: x["kind"] == y["kind"],
                            edge_match=lambda x, y: sorted(map(repr, (e["label"] for e in x.values())))
                            == sorted(map(repr, (e["label"] for e in y.values()))))


def _limb_graphs(cands):
    out = []
    for c in cands:
        t = c.template() or next(iter(parasynth.structures.TEMPLATES.values()))
        out.append(_joint_graph(_description(c, t, "x")))
    return out


def test_duplicate_removal_agrees_with_graph_isomorphism():
    cands = candidates(["SPS", "UPS", "RPU", "UPU"], all_axes=True)
    graphs = _limb_graphs(cands)
    keys = [_key(c.groups) for c in cands]
    # candidates the code calls duplicates are isomorphic; those it keeps apart are not (checked
    # on every pair with as many bodies and joints; others cannot be isomorphic)
    n_dup = n_apart = 0
    for i, j in itertools.combinations(range(len(cands)), 2):
        gi, gj = graphs[i], graphs[j]
        if (gi.number_of_nodes(), gi.number_of_edges()) != (gj.number_of_nodes(), gj.number_of_edges()):
            continue
        same_key = keys[i] == keys[j]
        assert _iso(gi, gj) == same_key, (cands[i].name, cands[j].name)
        n_dup += same_key
        n_apart += not same_key
    assert n_dup >= 10 and n_apart >= 10


@pytest.mark.parametrize("motion", per_motion(MOTIONS))
def test_no_two_kept_structures_are_isomorphic(motion):
    for found in (enumerated(motion),):
        graphs = [_joint_graph(s.description) for s in found]
        for (a, ga), (b, gb) in itertools.combinations(zip(found, graphs), 2):
            assert not _iso(ga, gb), (motion, a.key, b.key)
        assert len({s.key for s in found}) == len(found)


def test_the_isomorphism_check_can_fail():
    c = next(c for c in candidates(["SPS", "UPS"]) if c.name == "3-SPS&3-UPS")
    d = next(c for c in candidates(["SPS", "UPS"]) if c.name == "3-UPS&3-SPS")
    e = next(c for c in candidates(["SPS", "UPS"]) if c.name == "6-UPS")
    gc, gd, ge = _limb_graphs([c, d, e])
    assert _iso(gc, gd) and _key(c.groups) == _key(d.groups)
    assert not _iso(gc, ge)


# -- the vocabulary ---------------------------------------------------------------------------------
def test_registering_a_limb_type_extends_synthesis(monkeypatch):
    without = dict(LIMB_TYPES)
    rus = without.pop("RUS")
    monkeypatch.setattr(parasynth.structures.synthesis, "LIMB_TYPES", without)
    monkeypatch.setattr(parasynth.structures.vocabulary, "LIMB_TYPES", without)
    with pytest.raises(ValueError, match="unknown limb type 'RUS'"):
        structures("3T3R", leg_types=["UPS", "RUS"])
    assert "RUS" not in _leg_types(None)
    closed = ["UPS", "PUS"]  # closed-form limbs besides it: a short enumeration
    before = structures("3T3R", leg_types=closed, legs=[6])
    assert not any("RUS" in s.leg_counts for s in before)
    parasynth.structures.register_limb(rus)
    assert "RUS" in _leg_types(None)  # the default vocabulary holds it
    after = structures("3T3R", leg_types=closed + ["RUS"], legs=[6])
    assert {"6-RUS", "3-UPS&3-RUS"} <= _names(after) - _names(before)
    assert _names(before) <= _names(after)


@pytest.mark.parametrize("motion", per_motion(MOTIONS))
def test_structure_names_and_counts_follow_the_limbs(motion):
    for found in (enumerated(motion),):
        for s in found:
            legs = s.mechanism().legs
            assert sum(s.leg_counts.values()) == len(legs)
            assert sum(s.actuated_counts.values()) == s.mechanism().n_actuators
            counted = {}
            for leg in legs:
                counted[leg.joints] = counted.get(leg.joints, 0) + 1
            assert counted == s.leg_counts


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="motion must be written like '3T2R'"):
        structures("3X2R")
    with pytest.raises(ValueError, match="unknown limb type 'XYZ'; the vocabulary: SPS"):
        structures("3T2R", leg_types=["PUS", "XYZ"])
    with pytest.raises(ValueError, match="legs must be numbers of limbs"):
        structures("3T2R", legs=[1])
    with pytest.raises(ValueError, match="n_poses must be"):
        structures("3T2R", n_poses=0)
    s = structures("2T2R", leg_types=["RPU", "SPS"])[0]
    with pytest.raises(ValueError, match="unknown parameter.*base_radiuss"):
        s.mechanism(base_radiuss=0.3)
    with pytest.raises(ValueError, match="not a leg type"):
        parasynth.structures.register_limb(parasynth.structures.LimbType("XYZ", "P", False, 0, ("regular",)))


def test_shared_parameters_change_the_geometry():
    s = next(s for s in structures("3T3R", leg_types=["UPS"]) if s.name == "6-UPS")
    m1, m2 = s.mechanism(), s.mechanism(base_radius=0.35)
    assert np.allclose(np.linalg.norm(m2.legs[0].base[:2]), 0.35)
    assert not np.allclose(m1.inverse_kinematics(m1.home).actuators, m2.inverse_kinematics(m1.home).actuators)


# -- the RUS leg ------------------------------------------------------------------------------------
def _rus_mechanism(**params):
    d = {
        "name": "rus6_test",
        "parameters": {"b": "300 mm", "a": "150 mm", "h": "120 mm", "L": "350 mm", "sep": "20 deg"},
        "base": {"B": {"pattern": "paired", "n": 3, "radius": "b", "separation": "sep"}},
        "platform": {"A": {"pattern": "paired", "n": 3, "radius": "a", "phase": "60 deg", "separation": "sep"}},
        "legs": [{"type": "RUS", "base": "B", "platform": "A[5, 0, 1, 2, 3, 4]", "r_axis": "tangent",
                  "crank_length": "h", "link_length": "L", "actuated": "R"}],
        "task": {"coordinates": {"x": "length", "y": "length", "z": "length", "alpha": "angle", "beta": "angle",
                                 "gamma": "angle"},
                 "position": ["x", "y", "z"],
                 "orientation": {"convention": "xyz", "angles": ["alpha", "beta", "gamma"]},
                 "home": {"x": "0 mm", "y": "0 mm", "z": "400 mm", "alpha": "0 deg", "beta": "0 deg",
                          "gamma": "0 deg"}},
    }
    cls = description_class(d)
    return cls(cls.Params(**params))


def test_rus_inverse_kinematics_jacobian_and_round_trip():
    m = _rus_mechanism()
    assert m.actuators == tuple(f"t{i}" for i in range(1, 7))
    assert set(m.actuator_kinds.values()) == {"angle"}
    rng = np.random.default_rng(5)
    X = m.home + rng.uniform(-1, 1, (60, 6)) * [0.03, 0.03, 0.03, 0.08, 0.08, 0.08]
    ik = m.inverse_kinematics(X)
    X, q = X[ik.reachable], ik.actuators[ik.reachable]
    assert len(X) >= 20
    # the closure: |S - C| = link length, C on the crank circle
    p, R = m.pose(X)
    for k, leg in enumerate(m.legs):
        C = leg.base + leg.crank_length * leg._crank(q[:, k])
        S = p + R @ leg.platform
        assert np.allclose(np.linalg.norm(S - C, axis=1), leg.link_length, atol=1e-12)
        assert np.allclose((C - leg.base) @ leg.r_axis, 0, atol=1e-12)
    # the Jacobian against central differences of the inverse kinematics
    J = m.jacobian(X)
    eps = 1e-6
    fd = np.stack([(m.inverse_kinematics(X + eps * e).actuators - m.inverse_kinematics(X - eps * e).actuators)
                   / (2 * eps) for e in np.eye(6)], axis=-1)
    assert np.allclose(J, fd, atol=1e-5 * np.abs(J).max())
    # forward kinematics recovers the pose
    Xf = m.forward_kinematics(q[:5], guess=X[:5] + 0.002)
    assert np.allclose(Xf, X[:5], atol=1e-9)


def test_rus_wrenches_are_reciprocal_to_the_passive_joints():
    m = _rus_mechanism()
    X = m.home + np.random.default_rng(2).uniform(-1, 1, (30, 6)) * [0.03, 0.03, 0.03, 0.08, 0.08, 0.08]
    X = X[m.inverse_kinematics(X).reachable][:1]
    assert len(X) == 1
    _, states, p = m.leg_states(X)
    for leg, st in zip(m.legs, states):
        T = leg.joint_twists(st, p)[0]
        assert T.shape == (6, 6)
        w, scale = leg.actuation_wrench(st, p)
        power = T @ w[0]  # twists (v_P, omega), wrench (f, m_P): the power is the dot product
        assert np.allclose(power[1:], 0, atol=1e-12)  # U and S joints do no work against the link force
        assert abs(power[0] - scale[0]) < 1e-12  # the crank rate sees the rate scale
        assert reciprocal_basis(T[None], m.length_scale)[0].shape[0] == 0  # six freedoms: no constraint


def test_rus_description_errors():
    base = {"type": "RUS", "base": "B", "platform": "A", "crank_length": "100 mm", "link_length": "300 mm"}
    doc = {"name": "x", "base": {"B": {"pattern": "polygon", "n": 6, "radius": "300 mm"}},
           "platform": {"A": {"pattern": "polygon", "n": 6, "radius": "150 mm"}},
           "task": {"coordinates": {"z": "length"}, "position": ["0 mm", "0 mm", "z"], "home": {"z": "400 mm"}}}
    bad = dict(base)
    bad.pop("crank_length")
    with pytest.raises(DescriptionError, match="crank_length: required key of the RUS leg is missing"):
        description_class({**doc, "legs": [bad]})
    with pytest.raises(DescriptionError, match="its actuated joint is the revolute joint 'R'"):
        description_class({**doc, "legs": [{**base, "actuated": "U"}]})
    with pytest.raises(DescriptionError, match="cannot be passive"):
        description_class({**doc, "legs": [{**base, "actuated": "none"}]})
    with pytest.raises(ValueError, match="crank_direction must not be parallel to r_axis"):
        RUS("L", base=[0, 0, 0], platform=[0, 0, 0], r_axis=[0, 1, 0], crank_direction=[0, 2, 0])


# -- the command line ------------------------------------------------------------------------------
def test_cli_prints_candidates_and_writes_descriptions(tmp_path):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = cli.main(["structures", "2T2R", "--types", "RPU,SPS", "--out", str(tmp_path / "d")])
    text = out.getvalue()
    assert code == 0, err.getvalue()
    assert "2-RPU&2-SPS" in text and "verified:    2T2R" in text and "dropped: duplicate 1" in text
    files = sorted((tmp_path / "d").glob("*.yaml"))
    assert len(files) == text.count("written:") >= 1
    m = load_mechanism(str(files[0]))
    assert m.mobility(warn=False).type == "2T2R"


@pytest.mark.parametrize("args,needle", [
    (["structures", "3X2R"], "motion must be written like"),
    (["structures", "3T2R", "--types", "PUS,XYZ"], "unknown limb type 'XYZ'"),
    (["structures", "3T2R", "--legs", "five"], "--legs must be whole numbers"),
    (["structures", "3T2R", "--legs", "1"], "--legs must be numbers of limbs >= 2"),
])
def test_cli_bad_arguments(args, needle):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            code = cli.main(args)
        except SystemExit as e:
            code = e.code
    assert code == 2 and needle in err.getvalue(), err.getvalue()


# -- required axes --------------------------------------------------------------------------------
def test_required_axes_select_the_2rpu_2sps_freedoms():
    want = {"translations": ["x", "z"], "rotations": ["y", "moving x"]}
    found = structures("2T2R", leg_types=["RPU", "SPS", "UPS"], axes=want)
    assert "2-RPU&2-SPS" in _names(found) and found.dropped["other axes"] == 0
    for s in found:
        assert set(s.axes["translations"]) == {"x", "z"} and set(s.axes["rotations"]) == {"y", "moving x"}
    # the same freedoms read off the mechanism: the twists span x and z translations and the two
    # rotations at home (no y translation, no z rotation)
    m = found[0].mechanism()
    T = m.mobility(warn=False).twist_basis  # rows (v, omega) about the platform reference point
    assert np.allclose(T[:, [1, 5]], 0, atol=1e-9) and np.linalg.matrix_rank(T[:, [0, 2, 3, 4]]) == 4
    other = structures("2T2R", leg_types=["RPU", "SPS"], axes={"translations": "x,y"})
    assert len(other) == 0 and other.dropped["other axes"] >= 1
    with pytest.raises(ValueError, match="axes.translations: 2T2R has 2 translations, 1 axes given"):
        structures("2T2R", axes={"translations": ["x"]})
    with pytest.raises(ValueError, match="axes must be a mapping with the keys translations and/or rotations"):
        structures("2T2R", axes={"moves": ["x"]})


def test_cli_required_axes():
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = cli.main(["structures", "2T2R", "--types", "RPU,SPS", "--translations", "x,y"])
    assert code == 0 and "0 kept" in out.getvalue() and "other axes 2" in out.getvalue(), out.getvalue()


# -- arguments: order, repetition, resource limits ---------------------------------------------
def test_leg_types_order_and_repetition_do_not_matter():
    """The same limb types in any order, or one named twice, enumerate the same candidates in
    the registry's order: the same structures (names, descriptions), the same drops."""
    from parasynth.structures import candidates

    from parasynth.structures import StructureWarning

    a = structures("3T3R", leg_types=["PUS", "UPS", "SPS"], legs=6)
    with pytest.warns(StructureWarning, match=r"^leg_types: UPS given more than once, counted once$"):
        b = structures("3T3R", leg_types=["SPS", "UPS", "PUS", "UPS"], legs=[6])
    with pytest.warns(StructureWarning, match=r"^leg_types: SPS given more than once"):
        c = structures("3T3R", leg_types="UPS, SPS, PUS, SPS", legs=(6, 6))
    for x in (b, c):
        assert [s.key for s in x] == [s.key for s in a]
        assert [s.description for s in x] == [s.description for s in a]
        assert x.dropped == a.dropped and x.enumerated == a.enumerated
    # counted independently: every 6-limb candidate of the three types, each type once
    assert a.enumerated == len(candidates(["SPS", "UPS", "PUS"], [6]))
    # an interleaved structure names the type first in the registry first (SPS, UPS, PUS, ...)
    inter = [s.name for s in a if "&" in s.name]
    assert inter and all(n.split("&")[0][2:] in ("SPS", "UPS") for n in inter), inter


def test_limb_counts_no_candidate_has_are_said():
    """UPS and PUS rings have 3-6 limbs (regular 3-6, paired 4 and 6) and interleave as 3+3:
    9 limbs give nothing, with a warning; 6 and 9 give the 6-limb candidates, with a warning."""
    from parasynth.structures import StructureWarning, candidates

    with pytest.warns(StructureWarning, match=r"^legs: no candidate of the limb types UPS, PUS has 9 limbs "
                                              r"\(possible: 2, 3, 4, 5, 6\); nothing is enumerated"):
        none = structures("3T3R", leg_types=["PUS", "UPS"], legs=9)
    assert none.enumerated == 0 and len(none) == 0
    with pytest.warns(StructureWarning, match="those counts add nothing"):
        six = structures("3T3R", leg_types=["PUS", "UPS"], legs=[6, 9], n_poses=1)
    assert six.enumerated == len(candidates(["UPS", "PUS"], [6])) > 0


def test_pose_checks_beyond_the_budget_are_refused_before_any_work():
    import time

    from parasynth.structures import MAX_POSE_CHECKS, StructureError

    t0 = time.perf_counter()
    with pytest.raises(StructureError, match=r"^n_poses: 1024 poses for each of the (at least )?\d+ candidates"):
        structures("3T3R", n_poses=1024)
    assert time.perf_counter() - t0 < 5.0
    with pytest.raises(StructureError, match=r"^n_poses must be at most 1024"):
        structures("3T3R", n_poses=10**9)
    # within the budget it runs: the 5-PUS/UPU of 3T2R from PUS and UPU at 2 poses each, in its paired and
    # irregular rings (the regular one is singular at home)
    assert MAX_POSE_CHECKS >= 2
    found = structures("3T2R", leg_types=["PUS", "UPU"], n_poses=2)
    assert [(s.name, s.groups[0].arrangement) for s in found] == [("5-PUS/UPU", "paired"), ("5-PUS/UPU", "irregular")]
