"""Layouts of structural synthesis that are not singular, one singularity floor, nothing dropped
in silence (docs/structures.md).

Every check compares with a value computed apart from the enumerator: the singularity margin of
the description written to YAML and loaded again, the leg lengths of the shipped paper model, the
actuator values of an equivalent structure, anchor angles from the arrangement's formula.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
import yaml

import parasynth
from parasynth import cli
from parasynth.measures import usable
from parasynth.measures.usable import SINGULARITY_FLOOR, usable_workspace
from parasynth.mechanisms import described_class
from parasynth.structures import DROP_REASONS, structures, verdict_text
from parasynth.study import verify

from _enumerated import enumerated, motion_group, per_motion

MOTIONS = [f"{t}T{r}R" for t in range(4) for r in range(4) if t + r > 0]


def _home_margin_of_yaml(s) -> float:
    """The margin at the home pose of the structure's description, written and read back."""
    desc = yaml.safe_load(s.yaml())
    cls = described_class(desc, source="round trip")
    mech = cls(cls.Params())
    return float(np.asarray(mech.singularity_margin(np.atleast_2d(mech.home), engine="numpy")).ravel()[0])


def _every_axis(motion: str):
    """``structures(motion, all_axes=True)``, once per test process."""
    return enumerated(motion, True)


#: Motions whose kept structures include some below the floor at a checked pose (seed 0), and
#: which: five 1T3R 2-UPU&2-x (the 2-UPU&2-UPS with both UPS axis choices) with the spherical UPU's
#: axes (two forces through the platform centre) and the 3T3R 3-RRPS&3-PRRS; none of the motions
#: of the shipped studies.
LOW_AT_A_CHECKED_POSE = {"1T3R": 5, "3T3R": 1}


@pytest.mark.parametrize("motion", per_motion(MOTIONS))
def test_no_kept_structure_is_singular_at_home(motion):
    """Over every motion type and every joint-axis choice: each kept structure is controlled at
    its home pose at the default dimensions, with margin >= SINGULARITY_FLOOR, and the regular
    rings of four or more limbs that are singular there are listed under "singular at home"."""
    found = _every_axis(motion)
    low = []
    for s in found:
        m = _home_margin_of_yaml(s)
        assert m >= SINGULARITY_FLOOR, (motion, s.label, s.arrangement, m)
        assert m == pytest.approx(s.home_margin, rel=1e-9, abs=1e-12)
        if s.checked_margin >= SINGULARITY_FLOOR and s.controlled_poses == s.checked_poses:
            assert s.verified and verdict_text(s).startswith("verified: ")
        else:  # controlled at home, but near a singularity at a checked pose: kept, and said so
            assert not s.verified and verdict_text(s).startswith("NOT VERIFIED: ")
            low.append((s.name, s.arrangement))
    assert len(low) <= LOW_AT_A_CHECKED_POSE.get(motion, 0), low
    if motion == "3T3R":
        assert not {n for n, _ in low} - {"3-RRPS&3-PRRS"}, low
        assert {"6-PUS", "6-RUS"} <= set(found.dropped_names["singular at home"])
    if motion == "3T2R":
        assert {"5-PUS/UPU", "5-UPS/UPU", "5-RUS/UPU"} <= set(found.dropped_names["singular at home"])
    if motion in ("0T3R", "1T2R", "1T3R", "2T2R", "2T3R", "3T0R", "3T1R", "3T2R", "3T3R"):
        assert len(found) >= 1, motion


@motion_group("3T2R")
def test_regular_pentagon_is_singular_and_its_paired_and_irregular_rings_are_not():
    """The regular 5-PUS/UPU is the 2021 paper's first scheme (its pentagonal platform):
    singular at the symmetric pose; the structure is kept in its paired and irregular rings."""
    first = parasynth.load_mechanism("5pus_upu", platform="pentagonal")
    assert float(first.singularity_margin(np.atleast_2d(first.home), engine="numpy")[0]) < 1e-8
    arrs = sorted(s.groups[0].arrangement for s in _every_axis("3T2R") if s.name == "5-PUS/UPU")
    assert arrs == ["irregular", "irregular", "paired", "paired"]  # u_axis tangent and radial


def _angles(points) -> np.ndarray:
    return np.rad2deg(np.arctan2(points[:, 1], points[:, 0])) % 360.0


def test_paired_odd_and_irregular_anchors_follow_their_formulas():
    # paired, 5 limbs: limb i at 72 i + s_i base_separation/2, s_i = +1, -1, +1, -1, +1
    found5 = structures("3T2R", leg_types=["UPS", "UPU"])
    paired = next(x for x in found5 if x.groups[0].arrangement == "paired")
    mech = paired.mechanism(base_separation=math.radians(24), platform_separation=math.radians(16))
    base = np.array([leg.base for leg in mech.legs[:5]])
    sign = np.array([1, -1, 1, -1, 1])
    np.testing.assert_allclose(_angles(base), (72.0 * np.arange(5) + 12.0 * sign) % 360, atol=1e-9)
    np.testing.assert_allclose(np.hypot(base[:, 0], base[:, 1]), 0.3, atol=1e-12)
    irregular = next(x for x in found5 if x.groups[0].arrangement == "irregular")
    offs = {f"base_offset_{i}": math.radians(d) for i, d in zip(range(2, 6), (3, -4, 5, -6))}
    mech = irregular.mechanism(base_radius=0.2, **offs)
    base = np.array([leg.base for leg in mech.legs[:5]])
    np.testing.assert_allclose(_angles(base), (72.0 * np.arange(5) + np.array([0, 3, -4, 5, -6])) % 360, atol=1e-9)
    np.testing.assert_allclose(np.hypot(base[:, 0], base[:, 1]), 0.2, atol=1e-12)


def test_the_2018_paper_layout_is_a_point_of_the_shared_parametrisation():
    """2-RPU&2-SPS (An et al. 2018): RPU limbs at 350 mm / 75 mm on x, SPS limbs at 550 mm /
    150 mm on y: base_radius 350 mm, platform_radius 75 mm, second_base_scale 550/350,
    second_platform_scale 2, the irregular pair's offsets 0, home_tilt 15 deg (the paper's home
    theta). The leg lengths equal those of the shipped model (x a free coordinate) at random
    poses; the paper's singularity at theta = 0 (eq. (29)) is there, and its home is controlled."""
    s = next(x for x in structures("2T2R", leg_types=["RPU", "SPS"]) if x.name == "2-RPU&2-SPS")
    assert [g.arrangement for g in s.groups] == ["opposed", "irregular"]
    mech = s.mechanism(base_radius=0.35, platform_radius=0.075, second_base_scale=0.55 / 0.35,
                       second_platform_scale=2.0, base_offset_2=0.0, platform_offset_2=0.0,
                       home_tilt=math.radians(15), height=0.75)
    paper = parasynth.load_mechanism("2rpu_2sps", coupled=False)
    rng = np.random.default_rng(1)
    n = 40
    # structure (x, z, theta, psi); paper (x, z, psi, theta); the same rotation Ry(theta) Rx(psi)
    X = np.column_stack([rng.uniform(-0.2, 0.2, n), rng.uniform(0.6, 0.9, n), rng.uniform(-0.6, 0.6, n),
                         rng.uniform(-0.4, 0.4, n)])
    q = mech.inverse_kinematics(X).actuators
    qp = paper.inverse_kinematics(X[:, [0, 1, 3, 2]]).actuators
    # structure legs: RPU +x, RPU -x, SPS +y, SPS -y; paper legs: SPS -y, RPU +x, SPS +y, RPU -x
    np.testing.assert_allclose(q, qp[:, [1, 3, 2, 0]], rtol=1e-10, atol=1e-12)
    home = np.array([0.0, 0.75, math.radians(15), 0.0])
    np.testing.assert_allclose(mech.home, home, atol=1e-12)
    assert float(mech.singularity_margin(np.atleast_2d(home), engine="numpy")[0]) > SINGULARITY_FLOOR
    level = home.copy()
    level[2] = 0.0
    assert float(mech.singularity_margin(np.atleast_2d(level), engine="numpy")[0]) < 1e-9


def test_equivalent_structures_are_reported_as_one():
    """5-SPS/UPU and 5-UPS/UPU: the SPS only adds an idle spin, so the actuators and the
    singularity margin agree at random poses (computed on both); the UPS one is kept with the
    SPS one named in its label, and the SPS one is listed under "equivalent"."""
    both = structures("3T2R", leg_types=["SPS", "UPS", "UPU"])
    ups = next(s for s in both if s.groups[0].arrangement == "paired" and s.groups[0].limb == "UPS")
    assert ups.label == "5-UPS/UPU (also 5-SPS/UPU: idle spin)"
    assert "5-SPS/UPU" in both.dropped_names["equivalent"] and all(s.name != "5-SPS/UPU" for s in both)
    sps = next(s for s in structures("3T2R", leg_types=["SPS", "UPU"]) if s.groups[0].arrangement == "paired")
    a, b = ups.mechanism(), sps.mechanism()
    X = a.home + np.random.default_rng(2).uniform(-0.03, 0.03, (20, 5))
    np.testing.assert_allclose(a.inverse_kinematics(X).actuators, b.inverse_kinematics(X).actuators, rtol=1e-12)
    np.testing.assert_allclose(a.singularity_margin(X, engine="numpy"), b.singularity_margin(X, engine="numpy"),
                               rtol=1e-8)


def test_show_dropped_lists_every_drop_with_its_reason(capsys):
    types = ["UPS", "RPS", "PUS", "UPU"]  # closed-form limbs: a short enumeration
    found = structures("2T3R", leg_types=types, show_dropped=True)
    text = found.summary()
    # the 2022 paper's 4-UPS/1-RPS is under-actuated for 2T3R (four actuators, five freedoms)
    assert "4-UPS/RPS" in found.dropped_names["under-actuated"]
    assert f"under-actuated ({found.dropped['under-actuated']}; {DROP_REASONS['under-actuated']})" in text
    assert "4-UPS/RPS" in text and "over-actuated (" in text
    listed = sum(len(v) for k, v in found.dropped_names.items() if k != "duplicate")
    assert listed == sum(v for k, v in found.dropped.items() if k != "duplicate")
    assert "under-actuated (" not in structures("2T3R", leg_types=types).summary()  # counts only, unless asked
    assert cli.main(["structures", "2T3R", "--types", "UPS,RPS", "--show-dropped"]) == 0
    out = capsys.readouterr().out
    assert "  under-actuated (" in out and "4-UPS/RPS" in out and "verified:" in out and "floor 0.001" in out
    with pytest.raises(ValueError, match="^show_dropped must be True or False"):
        structures("2T3R", show_dropped="yes")


def test_verified_only_above_the_floor():
    s = structures("3T2R", leg_types=["PUS", "UPU"])[0]
    assert verdict_text(s).startswith("verified: ")
    low = dataclasses.replace(s, home_margin=2e-4, _cls=list(s._cls))
    text = verdict_text(low)
    assert text.startswith("NOT VERIFIED: ") and "margin 0.0002 at home" in text and "floor 0.001" in text
    low = dataclasses.replace(s, checked_margin=5e-4, _cls=list(s._cls))
    assert verdict_text(low).startswith("NOT VERIFIED: ")


def test_one_floor():
    """SINGULARITY_FLOOR is defined once (measures.usable) and re-exported; the usable
    workspace's floor is never below it, even relative to a singular home pose."""
    assert verify.SINGULARITY_FLOOR is usable.SINGULARITY_FLOOR == 1e-3
    from parasynth.study.spec import EvaluationSpec

    assert EvaluationSpec().singularity_floor == SINGULARITY_FLOOR
    singular = parasynth.load_mechanism("5pus_upu", platform="pentagonal")
    u = usable_workspace(singular, resolution=6)
    assert u.floor == SINGULARITY_FLOOR  # 2 % of a home margin of ~1e-16 would be ~0
    with pytest.raises(ValueError, match=r"^floor must be a number in \[0.001, 1.0\)"):
        usable_workspace(singular, resolution=6, floor=1e-4)


def test_a_structure_study_checks_each_design_against_its_own_floor():
    from parasynth.study import load_study

    d = yaml.safe_load(open("studies/structures_3t2r.yaml", encoding="utf-8"))
    s = load_study(yaml.safe_dump(d), is_text=True)
    c = next(c for c in s.constraints if c.name == "home_singularity_margin")
    assert c.label == "home_floor" and c.min == SINGULARITY_FLOOR
    d["evaluation"]["singularity_floor"] = 0.02
    s = load_study(yaml.safe_dump(d), is_text=True)
    assert next(c for c in s.constraints if c.name == "home_singularity_margin").min == 0.02
