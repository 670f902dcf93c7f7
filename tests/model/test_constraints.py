"""Pose constraints: segment distances against brute force, interference margins, names."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import parasynth
from parasynth.model.spatial import segment_distance


def brute_distance(p1, q1, p2, q2, n=401):
    """Minimum distance by dense sampling of both segments, refined around the best pair."""
    t = np.linspace(0, 1, n)
    A = p1 + t[:, None] * (q1 - p1)
    B = p2 + t[:, None] * (q2 - p2)
    D = np.linalg.norm(A[:, None, :] - B[None, :, :], axis=-1)
    i, j = np.unravel_index(np.argmin(D), D.shape)
    # refine on a finer grid around (i, j)
    ta = np.clip(np.linspace(t[i] - 2 / n, t[i] + 2 / n, 801), 0, 1)
    tb = np.clip(np.linspace(t[j] - 2 / n, t[j] + 2 / n, 801), 0, 1)
    A = p1 + ta[:, None] * (q1 - p1)
    B = p2 + tb[:, None] * (q2 - p2)
    return np.linalg.norm(A[:, None, :] - B[None, :, :], axis=-1).min()


coords = st.floats(-1, 1, allow_nan=False, width=64)
vec = st.tuples(coords, coords, coords).map(np.array)


@settings(max_examples=60, deadline=None)
@given(vec, vec, vec, vec)
def test_segment_distance_matches_brute_force(p1, q1, p2, q2):
    d = segment_distance(p1, q1, p2, q2)
    b = brute_distance(p1, q1, p2, q2)
    assert d <= b + 1e-12  # never above a sampled pair
    # the sampled minimum overestimates by up to about a grid step times the lengths
    scale = 1 + np.linalg.norm(q1 - p1) + np.linalg.norm(q2 - p2)
    assert d == pytest.approx(b, abs=2e-5 * scale)


def test_segment_distance_special_cases():
    o = np.zeros(3)
    x, y, z = np.eye(3)
    assert segment_distance(o, x, o + z, x + z) == pytest.approx(1.0)  # parallel, overlapping
    assert segment_distance(o, x, 2 * x + y, 3 * x + y) == pytest.approx(np.hypot(1, 1))  # parallel, disjoint
    assert segment_distance(o, o, y, y) == pytest.approx(1.0)  # two points
    assert segment_distance(-x, x, -y + 0.5 * z, y + 0.5 * z) == pytest.approx(0.5)  # crossing skew lines
    assert segment_distance(o, x, 0.5 * x - y, 0.5 * x + y) == pytest.approx(0.0)  # intersecting
    # vectorised over leading axes
    P = np.stack([o, o])
    np.testing.assert_allclose(segment_distance(P, P + x, P + z, P + z + x), [1.0, 1.0])


@pytest.mark.parametrize("name", ["5pus_upu", "4ups_1rps", "2rpu_2sps"])
def test_interference_margin_is_min_pairwise_distance_minus_diameter(name):
    mech = parasynth.load_mechanism(name)
    rng = np.random.default_rng(3)
    lo = np.array([r[0] for r in mech.default_ranges().values()])
    hi = np.array([r[1] for r in mech.default_ranges().values()])
    names = list(mech.default_ranges())
    X = np.tile(mech.home, (12, 1))
    idx = [mech.task_coordinates.index(c) for c in names]
    X[:, idx] = mech.home[idx] + 0.15 * (rng.uniform(lo, hi, (12, len(idx))) - mech.home[idx])
    ik = mech.inverse_kinematics(X)
    ok = ik.reachable
    assert ok.any()
    cons = mech.constraints["interference"]
    margins = mech.constraint_margins(X, names=["interference"])["interference"]
    pairs = cons._pairs([leg.name for leg in mech.legs])
    states = {leg.name: s for leg, s in zip(mech.legs, ik.legs)}
    for k in np.flatnonzero(ok):
        d = min(brute_distance(states[a].base_point[k], states[a].platform_point[k],
                               states[b].base_point[k], states[b].platform_point[k]) for a, b in pairs)
        assert margins[k] == pytest.approx(d - cons.diameter, abs=2e-5)
    assert np.all(margins[~ok] == -np.inf)


def test_unknown_constraint_names_list_valid():
    mech = parasynth.load_mechanism("5pus_upu")
    with pytest.raises(ValueError, match="valid: stroke"):
        mech.constraint_margins(mech.home, names=["strok"])
    with pytest.raises(ValueError, match="unknown constraint"):
        mech.is_feasible(mech.home, names="nope")


def test_stroke_margin_by_hand():
    mech = parasynth.load_mechanism("2rpu_2sps")
    X = np.array([0.65, np.deg2rad(25), np.deg2rad(15)])  # Table 1, case (a)
    q = np.array([736.8688, 639.0079, 844.7550, 807.5673]) * 1e-3
    expect = min(np.min(q - 0.7), np.min(1.0 - q))  # 639.0 mm is below the 700 mm minimum
    assert mech.constraint_margins(X)["stroke"] == pytest.approx(expect, abs=1e-6)
    assert not mech.is_feasible(X)


def _box_poses(mech, n, seed, spread=1.0):
    rng = np.random.default_rng(seed)
    ranges = mech.default_ranges()
    X = np.tile(mech.home, (n, 1))
    for c, (lo, hi) in ranges.items():
        j = mech.task_coordinates.index(c)
        mid = 0.5 * (lo + hi)
        X[:, j] = mid + spread * (rng.uniform(lo, hi, n) - mid)
    return X


def _chain_structure():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return parasynth.structures("3T2R", leg_types=["RPUR"])[0].mechanism()


@pytest.mark.parametrize("name", ["5pus_upu", "4ups_1rps", "2rpu_2sps", "chain 5-RPUR"])
def test_context_rows_give_the_margins_of_those_poses(name):
    """A constraint's margin at ctx.rows(idx) is its margin at those poses of the whole context,
    bit for bit: every margin is a function of each pose alone, and rows() carries every
    per-pose array (states, angles, a chain limb's solved coordinates)."""
    mech = _chain_structure() if name.startswith("chain") else parasynth.load_mechanism(name)
    X = _box_poses(mech, 300, 5, spread=1.6)
    ctx = mech.pose_context(X)
    idx = np.random.default_rng(6).permutation(300)[:97]
    sub = ctx.rows(idx)
    assert sub.X.shape[0] == sub.p.shape[0] == sub.actuators.shape[0] == 97
    np.testing.assert_array_equal(sub.reachable, ctx.reachable[idx])
    both = False
    for cname, c in mech.constraints.items():
        with np.errstate(invalid="ignore"):
            whole, part = np.asarray(c.margin(ctx)), np.asarray(c.margin(sub))
        np.testing.assert_array_equal(part, whole[idx], err_msg=cname)
        both |= bool(np.any(part >= 0) and np.any(part < 0))
    assert both  # poses inside and outside a constraint among the rows


@pytest.mark.parametrize("name", ["5pus_upu", "2rpu_2sps", "chain 5-RPUR"])
def test_feasibility_by_rows_is_every_constraint_at_every_pose(name):
    """is_feasible (NumPy, and the chain engine) evaluates each constraint only at the poses the
    ones before it left feasible: the answer is the conjunction of every margin at every pose,
    computed here the long way."""
    from parasynth.model.constraints import feasible_rows

    mech = _chain_structure() if name.startswith("chain") else parasynth.load_mechanism(name)
    X = _box_poses(mech, 400, 7, spread=1.6)
    ctx = mech.pose_context(X)
    expected = ctx.reachable.copy()
    with np.errstate(invalid="ignore"):
        for c in mech.constraints.values():
            expected &= np.asarray(c.margin(ctx)) >= 0
    assert 0 < expected.sum() < 0.5 * len(X)  # the subset path taken, and feasible poses left
    np.testing.assert_array_equal(feasible_rows(ctx, list(mech.constraints.values())), expected)
    np.testing.assert_array_equal(mech.is_feasible(X, engine="numpy"), expected)
    if name.startswith("chain"):
        np.testing.assert_array_equal(mech.is_feasible(X), expected)
