"""Robust measures (parasynth.measures.robustness): values under scatter checked against Monte Carlo
computations written here (parameters and anchors perturbed directly, the actual pose found by
the model's own forward kinematics), first-order values against finite differences, a chance
constraint against its closed form, the mechanism as built on legs of lower mobility (3-RPS,
5-PUS/UPU), and the robust block of a study."""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest

import parasynth
from parasynth import load_mechanism
from parasynth.measures.accuracy import closure_residuals
from parasynth.measures.objectives import get as get_measure
from parasynth.measures.robustness import AsBuilt, RobustError, RobustMeasure, robust
from parasynth.study.errors import StudyError
from parasynth.study.evaluate import Evaluator
from parasynth.study.spec import load_study
from parasynth.measures.workspace import WorkspaceSample

GS = "gough_stewart_6ups"
# positions around home at the home orientation; the stroke and joint limits cut the box
GS_SAMPLE = WorkspaceSample(ranges={"x": (-0.3, 0.3), "y": (-0.3, 0.3), "z": (0.3, 0.95)}, n=512, method="random",
                            seed=0)


def _band(se_a, se_b):
    return 3.0 * math.sqrt(se_a ** 2 + se_b ** 2)


def _quantile_se(v, level):
    """Standard error of a sample quantile from the binomial spread of the order statistics."""
    s = np.sort(np.asarray(v))
    k = len(s)
    half = math.sqrt(k * level * (1 - level))
    lo = int(np.clip(math.floor(k * level - half), 0, k - 1))
    hi = int(np.clip(math.ceil(k * level + half), 0, k - 1))
    return 0.5 * (s[hi] - s[lo])


def _as_built_by_fk(mech, rng, tol, X, act_tol=0.0):
    """One independent draw: every anchor coordinate of every leg moved uniformly within +-tol,
    the actuators held at the nominal inverse kinematics plus an error uniform in +-act_tol, the
    actual pose found by the model's forward kinematics from the nominal pose; (feasible (N,),
    actual poses (N, 6), mechanism)."""
    legs = [dataclasses.replace(leg, base=leg.base + rng.uniform(-tol, tol, 3),
                                platform=leg.platform + rng.uniform(-tol, tol, 3)) for leg in mech.legs]
    dq = rng.uniform(-act_tol, act_tol, len(legs))
    pm = copy.copy(mech)
    pm.legs = tuple(legs)
    ik = mech.inverse_kinematics(X)
    Xa = np.asarray(pm.forward_kinematics(np.where(ik.reachable[:, None], ik.actuators + dq, 0.0),
                                          guess=np.where(ik.reachable[:, None], X, mech.home)))
    ok = ik.reachable & pm.is_feasible(Xa, engine="numpy")
    return ok, Xa, pm


@pytest.fixture(scope="module")
def gs():
    return load_mechanism(GS)


def _sample_points(mech, sample):
    """The points of a "random" workspace sample: uniform in the box from the sample's seed."""
    lo = np.array([r[1][0] for r in sample.ranges])
    hi = np.array([r[1][1] for r in sample.ranges])
    X = np.tile(mech.home, (sample.n, 1))
    X[:, :3] = lo + (hi - lo) * np.random.default_rng(sample.seed).random((sample.n, 3))
    return X


# -- robust values against an independent Monte Carlo ---------------------------------------------
def test_parameter_scatter_volume_and_margin_quantile_agree_with_monte_carlo(gs):
    tol = 0.02  # base_radius +-20 mm
    k = 24
    vol = robust("workspace_volume", tolerances={"base_radius": tol, "platform_radius": tol}, samples=k, seed=3)
    smq = robust("singularity_margin_min", tolerances={"base_radius": tol, "platform_radius": tol},
                 statistic="quantile", level=0.25, samples=k, seed=3)
    rv = vol.evaluate(gs, sample=GS_SAMPLE)
    rq = smq.evaluate(gs, sample=GS_SAMPLE, quantile=0.05)
    assert rv.standard_error > 0 and rq.standard_error > 0
    rng = np.random.default_rng(12345)
    v_mc, q_mc = [], []
    for _ in range(10 * k):
        m = load_mechanism(GS, base_radius=0.5 + rng.uniform(-tol, tol), platform_radius=0.3 + rng.uniform(-tol, tol))
        v_mc.append(get_measure("workspace_volume")(m, sample=GS_SAMPLE))
        q_mc.append(get_measure("singularity_margin_min")(m, sample=GS_SAMPLE, quantile=0.05))
    v_mc, q_mc = np.array(v_mc), np.array(q_mc)
    assert np.std(v_mc) > 0.005 * np.mean(v_mc)  # the scatter moves the volume
    se_mc = np.std(v_mc, ddof=1) / math.sqrt(len(v_mc))
    assert abs(rv.value - v_mc.mean()) <= _band(rv.standard_error, se_mc)
    qm = np.quantile(q_mc, 0.25)
    assert abs(rq.value - qm) <= _band(rq.standard_error, _quantile_se(q_mc, 0.25))


@pytest.mark.parametrize("act_tol", [0.0, 2e-3])
def test_anchor_scatter_volume_and_margin_quantile_agree_with_monte_carlo_by_forward_kinematics(act_tol):
    # tighter joint limits than the model's defaults: the cone limits bind beside the stroke (the
    # stroke alone does not feel anchor errors, the actuators hold their values)
    gs = load_mechanism(GS, ujoint_max=0.3, sphere_max=0.4)
    tol = 3e-3  # every anchor coordinate +-3 mm
    k = 12
    tols = {"anchor_tolerance": tol, "actuator_tolerance": act_tol}
    vol = robust("workspace_volume", tolerances=tols, samples=k, seed=5)
    smq = robust("singularity_margin_min", tolerances=tols, samples=k, seed=5)
    rv = vol.evaluate(gs, sample=GS_SAMPLE)
    rq = smq.evaluate(gs, sample=GS_SAMPLE, quantile=0.05)
    X = _sample_points(gs, GS_SAMPLE)
    box = 0.6 * 0.6 * 0.65
    # the sample points rebuilt here are the measure's: the nominal volume agrees
    assert np.count_nonzero(gs.is_feasible(X)) / len(X) * box == pytest.approx(rv.nominal, rel=1e-12)
    assert np.std(rv.values) > 0.005 * rv.nominal  # the scatter moves the volume
    rng = np.random.default_rng(777)
    v_mc, q_mc = [], []
    for _ in range(10 * k):
        ok, Xa, pm = _as_built_by_fk(gs, rng, tol, X, act_tol)
        v_mc.append(np.count_nonzero(ok) / len(X) * box)
        sm = pm.singularity_margin(Xa[ok], engine="numpy")
        q_mc.append(np.quantile(sm[np.isfinite(sm)], 0.05))
    v_mc, q_mc = np.array(v_mc), np.array(q_mc)
    assert np.std(v_mc) > 0.005 * rv.nominal
    assert abs(rv.value - v_mc.mean()) <= _band(rv.standard_error, np.std(v_mc, ddof=1) / math.sqrt(len(v_mc)))
    assert abs(rq.value - q_mc.mean()) <= _band(rq.standard_error, np.std(q_mc, ddof=1) / math.sqrt(len(q_mc)))


def test_first_order_agrees_with_finite_differences(gs):
    tols = {"base_radius": 1e-3, "platform_radius": 2e-3}
    rm = robust("home_singularity_margin", tolerances=tols, statistic="first_order")
    r = rm.evaluate(gs)
    f = get_measure("home_singularity_margin")
    v0 = f(gs)
    h = 1e-6
    bound = 0.0
    for name, t in tols.items():
        x0 = getattr(gs.params, name)
        d = (f(load_mechanism(GS, **{name: x0 + h})) - f(load_mechanism(GS, **{name: x0 - h}))) / (2 * h)
        bound += abs(d) * t
    assert bound > 0
    assert r.nominal == pytest.approx(v0, rel=1e-12)
    assert r.standard_error is None
    assert r.value == pytest.approx(v0 - bound, rel=1e-6)  # the margin is maximised: the worse side is below


def test_first_order_per_leg_agrees_with_finite_differences_by_forward_kinematics(gs):
    tol = 1e-4
    r = robust("home_singularity_margin", tolerances={"anchor_tolerance": tol}, statistic="first_order").evaluate(gs)
    q0 = gs.inverse_kinematics(gs.home[None]).actuators
    h = 1e-6

    def value(li, end, c, delta):
        legs = list(gs.legs)
        a = getattr(legs[li], end).copy()
        a[c] += delta
        legs[li] = dataclasses.replace(legs[li], **{end: a})
        pm = copy.copy(gs)
        pm.legs = tuple(legs)
        Xa = np.asarray(pm.forward_kinematics(q0, guess=gs.home[None]))
        return float(pm.singularity_margin(Xa, engine="numpy")[0])

    bound = sum(abs(value(li, end, c, h) - value(li, end, c, -h)) / (2 * h) * tol
                for li in range(6) for end in ("base", "platform") for c in range(3))
    assert bound > 0
    assert r.value == pytest.approx(r.nominal - bound, rel=1e-4)


def test_first_order_is_refused_for_a_measure_counted_on_samples():
    with pytest.raises(RobustError, match=r"statistic: first_order .* counted on workspace samples"):
        robust("workspace_volume", tolerances={"anchor_tolerance": 1e-5}, statistic="first_order")


def test_worst_is_the_least_favourable_draw(gs):
    rm = robust("workspace_volume", tolerances={"base_radius": 0.02}, statistic="worst", samples=8, seed=1)
    r = rm.evaluate(gs, sample=GS_SAMPLE)
    assert r.standard_error is None
    assert r.value == min(r.values) and len(r.values) == 8
    # common random numbers: the same draws again, the same value
    assert rm(gs, sample=GS_SAMPLE) == r.value


# -- a chance constraint with a closed form -------------------------------------------------------
def test_chance_constraint_probability_matches_the_closed_form():
    """The 5-PUS/UPU's footprint is its slider radius r; with r drawn uniformly in r0 +- t, the
    chance of footprint <= r0 + m is (t + m) / (2 t)."""
    m = load_mechanism("5pus_upu")
    r0 = m.params.slider_radius
    assert get_measure("footprint_radius")(m) == pytest.approx(r0)
    t, margin, k = 1e-3, 0.3e-3, 400
    rm = robust("footprint_radius", tolerances={"slider_radius": t}, samples=k, seed=2)
    P, se, nominal = rm.probability_of(m, ("max", r0 + margin))
    exact = (t + margin) / (2 * t)
    assert se == pytest.approx(math.sqrt(P * (1 - P) / k))
    assert abs(P - exact) <= 3 * math.sqrt(exact * (1 - exact) / k)
    assert nominal == pytest.approx(r0)


# -- the mechanism as built ------------------------------------------------------------------------
def test_3rps_anchor_moved_along_its_revolute_axis_is_built_not_re_solved():
    m = load_mechanism("3rps")
    leg = m.legs[0]
    legs = [dataclasses.replace(leg, base=leg.base + 5e-5 * leg.r_axis), *m.legs[1:]]
    X = m.home[None, :]
    p0, R0 = m.pose(X)
    # re-solving the inverse kinematics at the nominal pose: the moved leg cannot reach it
    assert not legs[0].solve(p0, R0).reachable[0]
    ab = AsBuilt(m, legs, np.zeros(3), {"m": 1e-3, "rad": 1e-2})
    ctx = ab.pose_context(X)
    assert ctx.reachable[0]
    # the actuators hold their nominal values and the perturbed closure holds at the actual pose
    assert np.allclose(closure_residuals(m, ctx.p, ctx.R, legs=legs), closure_residuals(m, p0, R0), atol=1e-12)
    assert np.allclose(ctx.actuators, m.inverse_kinematics(X).actuators, atol=1e-12)
    moved = np.linalg.norm(ctx.p - p0)
    assert 1e-6 < moved < 1e-3
    assert ab.is_feasible(X)[0] == bool(np.all([v[0] >= 0 for v in ab.constraint_margins(X).values()]))


def test_3rps_robust_home_margin_under_anchor_scatter():
    m = load_mechanism("3rps")
    r = robust("home_singularity_margin", tolerances={"anchor_tolerance": "0.05 mm"}, samples=8).evaluate(m)
    assert all(v > 0 for v in r.values)  # every draw reaches home as built
    assert abs(r.value - r.nominal) < 0.01 * r.nominal and r.value != r.nominal


def test_5pus_upu_as_built_closure_and_screened_feasibility():
    m = load_mechanism("5pus_upu")
    rm = robust("workspace_volume", tolerances={"anchor_tolerance": "0.05 mm", "axis_tolerance": "0.02 deg",
                                                "actuator_tolerance": "0.01 mm"}, samples=3, seed=4)
    draws = rm.draws(m)
    assert all(isinstance(d, AsBuilt) for d in draws)
    rng = np.random.default_rng(0)
    X = np.zeros((400, 5))
    X[:, :3] = rng.uniform([-0.12, -0.12, -0.4], [0.12, 0.12, 0.2], (400, 3))
    X[:, 3:] = rng.uniform(-0.2, 0.2, (400, 2))
    ik = m.inverse_kinematics(X)
    p0, R0 = m.pose(X)
    h0 = closure_residuals(m, p0, R0)
    for d in draws:
        ctx = d.pose_context(X)
        ok = ctx.reachable
        assert ok[ik.reachable].mean() > 0.9
        r = closure_residuals(m, ctx.p[ok], ctx.R[ok], legs=list(d.legs))
        target = h0[ok].copy()
        target[:, :5] += d.dq
        # sliders at their commanded values, the UPU leg's twist constraint holds at the actual pose
        assert np.allclose(r, target, atol=1e-11)
        # the screened feasibility is the unscreened as-built evaluation
        full = np.logical_and.reduce([v >= 0 for v in d.constraint_margins(X).values()])
        assert np.array_equal(d.is_feasible(X), full)
        assert np.count_nonzero(full) > 20


def test_under_actuated_per_leg_scatter_is_refused():
    m = load_mechanism("4ups_1rps")
    rm = robust("home_singularity_margin", tolerances={"anchor_tolerance": "0.02 mm"}, samples=2)
    with pytest.raises(ValueError, match="under-actuated"):
        rm.check(m)


def test_over_constrained_per_leg_scatter_is_refused_and_parameter_scatter_is_not():
    """The 2-RPU&2-SPS has two redundant constraints (its RPU legs' parallel revolute axes): a
    perturbed rigid closure of it has no solution, so per-leg scatter is refused by name, while
    parameter scatter (which keeps the axes parallel) is checked and evaluates."""
    m = load_mechanism("2rpu_2sps")
    X = m.home[None, :]
    # the reason, independently: with a 0.02 mm anchor error the least-squares closure leaves a residual
    from parasynth.measures.accuracy import _check_tolerances, _perturbed_legs, _sample_errors, error_sources
    src = error_sources(m)
    e = _sample_errors(src, _check_tolerances({"anchor_tolerance": 2e-5}), 1, np.random.default_rng(0))[0]
    assert not AsBuilt(m, _perturbed_legs(m, src, e), np.zeros(0), {}).pose_context(X).reachable[0]
    rm = robust("home_singularity_margin", tolerances={"anchor_tolerance": "0.02 mm"}, samples=2)
    with pytest.raises(ValueError, match="redundant constraints"):
        rm.check(m)
    ok = robust("home_singularity_margin", tolerances={"b1": "0.05 mm"}, samples=4)
    ok.check(m)
    v = ok.evaluate(m)
    assert np.isfinite(v.value) and abs(v.value - v.nominal) < 0.05 * abs(v.nominal)


def test_stacked_draws_equal_draws_evaluated_one_by_one(monkeypatch):
    """Parameters and legs scattered together: the draws solved as one stacked batch (each row
    with its draw's rebuilt legs, neutral joint directions included, screened by the design's
    margins) give, draw by draw, the values of each draw evaluated alone on its own legs."""
    from parasynth.measures import robustness as rb

    m = load_mechanism("5pus_upu")
    tol = {"slider_radius": "0.05 mm", "link_length": "0.05 mm", "anchor_tolerance": "0.02 mm",
           "axis_tolerance": "0.01 deg", "actuator_tolerance": "0.01 mm"}
    out = {}
    for stacked in (True, False):
        if not stacked:
            monkeypatch.setattr(rb._Group, "stackable", lambda self: False)
        for name in ("workspace_volume", "singularity_margin_min"):
            rb._DRAW_CACHE.clear()
            out[stacked, name] = robust(name, tolerances=tol, samples=8, seed=0).values(m, n=4096)
    np.testing.assert_array_equal(out[True, "workspace_volume"], out[False, "workspace_volume"])
    np.testing.assert_allclose(out[True, "singularity_margin_min"], out[False, "singularity_margin_min"],
                               rtol=1e-6)
    assert np.ptp(out[True, "workspace_volume"]) > 0  # the draws differ: the comparison is not of copies


@pytest.mark.parametrize("name,tol", [
    ("5pus_upu", {"anchor_tolerance": "0.02 mm", "axis_tolerance": "0.01 deg", "actuator_tolerance": "0.01 mm"}),
    ("5pus_upu", {"slider_radius": "0.05 mm", "anchor_tolerance": "0.05 mm", "link_tolerance": "0.05 mm"}),
    ("3rps", {"anchor_tolerance": "0.05 mm", "axis_tolerance": "0.02 deg", "actuator_tolerance": "0.02 mm"}),
])
def test_margins_on_the_shell_only_equal_margins_at_every_candidate_pose(monkeypatch, name, tol):
    """The stacked draws evaluate the constraint margins at the actual pose only on the shell
    (a nominal margin within the band); evaluating them at every candidate pose gives the same
    feasibility, draw by draw, so the same volumes and margins."""
    from parasynth.measures import robustness as rb

    m = load_mechanism(name)
    out = {}
    for shell in (True, False):
        monkeypatch.setattr(rb, "SHELL_ONLY", shell)
        for measure in ("workspace_volume", "singularity_margin_min"):
            rb._DRAW_CACHE.clear()
            out[shell, measure] = robust(measure, tolerances=tol, samples=8, seed=2).values(m, n=4096)
    np.testing.assert_array_equal(out[True, "workspace_volume"], out[False, "workspace_volume"])
    np.testing.assert_allclose(out[True, "singularity_margin_min"], out[False, "singularity_margin_min"], rtol=1e-12)
    assert np.ptp(out[True, "workspace_volume"]) > 0


# -- the Python interface --------------------------------------------------------------------------
def test_robust_is_a_measure_with_the_base_settings():
    rm = parasynth.robust("singularity_margin_min", tolerances={"anchor_tolerance": "0.02 mm"}, statistic="quantile",
                          level=0.05, samples=16, seed=1)
    assert isinstance(rm, RobustMeasure) and rm.params == get_measure("singularity_margin_min").params
    assert rm.sense == "maximize" and rm.samples == 16 and rm.leg_tolerances == (("anchor_tolerance", 2e-05),)


@pytest.mark.parametrize("kw,needle", [
    ({"statistic": "median"}, "statistic: must be one of mean, quantile, worst, first_order"),
    ({"statistic": "quantile"}, "level"),
    ({"statistic": "quantile", "level": 1.0}, "level"),
    ({"samples": 1}, "samples"),
    ({"seed": -1}, "seed"),
    ({"tolerances": {"anchor_tolerance": "1 kg"}}, "tolerances.anchor_tolerance"),
    ({"tolerances": {"anchor_tolerance": -1e-3}}, "tolerances.anchor_tolerance"),
    ({"tolerances": {}}, "tolerances"),
    ({"tolerances": {"anchor_tolerance": 0.0}}, "at least one positive tolerance"),
])
def test_bad_python_input_names_the_field(kw, needle):
    args = {"tolerances": {"anchor_tolerance": 1e-5}, **kw}
    with pytest.raises(ValueError, match=needle):
        robust("home_singularity_margin", **args)


def test_unknown_parameter_is_refused_on_the_mechanism():
    rm = robust("home_singularity_margin", tolerances={"nope_radius": "1 mm"})
    with pytest.raises(ValueError, match="nope_radius"):
        rm(load_mechanism("3rps"))


# -- the robust block of a study -------------------------------------------------------------------
STUDY = """
name: robust_probe
mechanism: 5pus_upu
variables:
  - {name: link_length, low: 180 mm, high: 230 mm}
objectives:
  - {name: workspace_volume, label: volume, robust: {tolerances: {slider_radius: 0.1 mm, anchor_tolerance: 0.02 mm},
     statistic: quantile, level: 0.1, samples: 4}}
constraints:
  - {name: footprint_radius, label: footprint, max: 135.05 mm, robust: {tolerances: {slider_radius: 0.1 mm},
     probability: 0.5, samples: 64}}
evaluation: {samples: 2048, ranges: {x: [-200 mm, 200 mm], y: [-200 mm, 200 mm], z: [-450 mm, 300 mm]}}
optimizer: {kind: sweep, designs: [{link_length: 205 mm}]}
"""


def test_study_records_robust_and_nominal_values():
    s = load_study(STUDY, is_text=True)
    rec = Evaluator(s).evaluate({"link_length": 0.205})
    assert rec.status == "ok", rec.error
    info = rec.robust["volume"]
    assert info["statistic"] == "quantile" and info["level"] == 0.1 and info["stderr"] >= 0
    assert info["nominal"] == pytest.approx(get_measure("workspace_volume")(
        load_mechanism("5pus_upu", link_length=0.205), sample=Evaluator(s).sample()))
    # the chance constraint: P(r <= r0 + 0.05 mm) = 0.75 for r uniform in r0 +- 0.1 mm
    P = rec.constraint_values["footprint"]
    assert abs(P - 0.75) <= 3 * math.sqrt(0.75 * 0.25 / 64)
    assert rec.margins["footprint"] == pytest.approx(P - 0.5)
    assert rec.robust["footprint"]["stderr"] == pytest.approx(math.sqrt(P * (1 - P) / 64))
    from parasynth.study.tables import results_table

    row = results_table(s, [rec]).iloc[0]
    assert row["volume_nominal"] == info["nominal"] and row["footprint_robust_se"] > 0


def test_a_chance_constraint_survives_the_run_copy_of_its_study():
    """The run directory keeps the study as resolved (defaults written out, statistic: mean among
    them): it must load again, or the run could not be resumed nor reported."""
    s = load_study(STUDY, is_text=True)
    again = load_study(s.to_yaml(), is_text=True)
    assert [c.probability for c in again.constraints] == [c.probability for c in s.constraints]


@pytest.mark.parametrize("change,needle", [
    (("statistic: quantile, level: 0.1", "statistic: median"),
     "objectives[0].robust.statistic: must be one of mean, quantile, worst, first_order"),
    (("anchor_tolerance: 0.02 mm", "anchor_tolerance: 0.02"), "objectives[0].robust.tolerances.anchor_tolerance"),
    (("slider_radius: 0.1 mm, anchor", "hinge_layout: 0.1 mm, anchor"), "objectives[0].robust.tolerances.hinge_layout"),
    (("statistic: quantile, level: 0.1", "statistic: first_order"), "objectives[0].robust.statistic"),
    (("probability: 0.5", "probability: 0"), "constraints[0].robust.probability"),
    (("samples: 4", "samples: 4, probability: 0.9"), "objectives[0].robust.probability"),
    (("samples: 4", "samples: 4, draws: 3"), "objectives[0].robust.draws"),
    # a chance constraint counts the draws within the bound: a statistic is refused (the default,
    # mean, which a run's copy of the study file writes out, is accepted: see below)
    (("probability: 0.5,", "probability: 0.5, statistic: worst,"), "constraints[0].robust.statistic: a chance "
                                                                    "constraint (probability)"),
    (("probability: 0.5,", "probability: 0.5, level: 0.2,"), "constraints[0].robust.level"),
    (("probability: 0.5,", "probability: 0.5, statistic: quantile, level: 0.1,"), "constraints[0].robust.statistic"),
])
def test_bad_robust_block_names_the_field(change, needle):
    text = STUDY.replace(*change)
    assert text != STUDY
    with pytest.raises(StudyError) as e:
        load_study(text, is_text=True)
    assert needle in str(e.value)


# -- arguments of the API: bounds, the applicability rule, the measure ---------------------------
BAD_BOUNDS = [("max",), "max", ("less", 0.1), ("min", float("nan")), ("max", float("inf")), ("min", "0.1"),
              ("min", True), [("min", 0.1)], ("min", 0.1, 2), 5, ("MIN", 0.1), (None, 0.1), ("min", 0.1 + 0j)]


@pytest.mark.parametrize("bound", BAD_BOUNDS, ids=[repr(b) for b in BAD_BOUNDS])
def test_bad_bound_is_refused_naming_it(bound):
    m = load_mechanism("5pus_upu")
    rm = robust("footprint_radius", tolerances={"slider_radius": 1e-4}, samples=4)
    for call in (rm.evaluate, rm.probability_of):
        with pytest.raises(RobustError, match=r"^bound"):
            call(m, bound)


def test_bound_sides_and_a_missing_bound():
    """A chance constraint needs its bound; a list is a bound as a tuple is; the sides count the
    draws on the right side of it (r uniform in r0 +- t: P(r >= r0) = 1/2 within its error)."""
    m = load_mechanism("5pus_upu")
    r0, t, k = m.params.slider_radius, 1e-3, 400
    rm = robust("footprint_radius", tolerances={"slider_radius": t}, samples=k, seed=1)
    with pytest.raises(RobustError, match=r"^bound must be .* for a chance constraint, got None"):
        rm.probability_of(m, None)
    P_min, _, _ = rm.probability_of(m, ["min", r0])
    P_max, _, _ = rm.probability_of(m, ("max", np.float32(r0)))
    assert abs(P_min - 0.5) <= 3 * math.sqrt(0.25 / k) and abs(P_max - 0.5) <= 3 * math.sqrt(0.25 / k)
    assert P_min + P_max == pytest.approx(1.0, abs=2.0 / k)  # only draws at r0 exactly count twice
    # evaluate without a bound takes the measure's sense: the worst footprint is the largest
    w = robust("footprint_radius", tolerances={"slider_radius": t}, samples=k, seed=1, statistic="worst")
    assert w.evaluate(m).value == pytest.approx(max(w.values(m))) and w.evaluate(m).value <= r0 + t


def test_per_leg_scatter_on_a_redundantly_constrained_mechanism_is_refused_as_in_a_study():
    """The 2-RPU&2-SPS has 2 redundant constraints: per-leg scatter is refused by every API entry
    point with the message the study's check gives; scatter of its description parameters is not."""
    m = load_mechanism("2rpu_2sps")
    rm = robust("home_singularity_margin", tolerances={"anchor_tolerance": "0.02 mm"}, samples=4)
    msgs = []
    for call in (lambda: rm.evaluate(m), lambda: rm.probability_of(m, ("min", 0.0)), lambda: rm.values(m),
                 lambda: rm(m), lambda: rm.draws(m), lambda: rm.check(m)):
        with pytest.raises(RobustError) as e:
            call()
        msgs.append(str(e.value))
    assert len(set(msgs)) == 1 and "2rpu_2sps: per-leg scatter (tolerances anchor_tolerance) needs a mechanism " \
                                   "without redundant constraints (2 here)" in msgs[0], msgs
    study = STUDY.replace("mechanism: 5pus_upu", "mechanism: 2rpu_2sps").replace(
        "variables:\n  - {name: link_length, low: 180 mm, high: 230 mm}",
        "variables:\n  - {name: a1, low: 140 mm, high: 160 mm}").replace(
        "tolerances: {slider_radius: 0.1 mm, anchor_tolerance: 0.02 mm}", "tolerances: {anchor_tolerance: 0.02 mm}")
    study = study.split("constraints:")[0] + "evaluation: {samples: 64, ranges: {z: [550 mm, 1000 mm], " \
                                             "psi: [-30 deg, 30 deg], theta: [-45 deg, 45 deg]}}\n" \
                                             "optimizer: {kind: sweep, designs: [{a1: 150 mm}]}\n"
    from parasynth.study.spec import check_study

    problems = check_study(load_study(study, is_text=True))
    assert any("objectives[0].robust.tolerances" in p and msgs[0] in p for p in problems), problems
    # description parameters keep the constraints consistent: accepted, values near the nominal
    ok = robust("footprint_radius", tolerances={"a1": "0.1 mm"}, samples=4).evaluate(m)
    assert all(abs(v - ok.nominal) <= 1e-4 + 1e-12 for v in ok.values)


def test_robust_of_a_measure_object_is_robust_of_its_name():
    m = load_mechanism("5pus_upu")
    by_name = robust("footprint_radius", tolerances={"slider_radius": 1e-3}, samples=16, seed=3)
    by_obj = robust(get_measure("footprint_radius"), tolerances={"slider_radius": 1e-3}, samples=16, seed=3)
    assert by_obj.name == by_name.name == "robust:footprint_radius"
    assert by_obj.evaluate(m).values == by_name.evaluate(m).values
    with pytest.raises(RobustError, match=r"^robust: 'robust:footprint_radius' is already robust"):
        robust(by_name, tolerances={"slider_radius": 1e-3})
    unregistered = dataclasses.replace(get_measure("footprint_radius"), name="my_footprint")
    with pytest.raises(RobustError, match=r"^robust: name must be a registered measure or its name"):
        robust(unregistered, tolerances={"slider_radius": 1e-3})
    for bad in (5, None, ["footprint_radius"], {"name": "footprint_radius"}):
        with pytest.raises(RobustError, match=r"^robust: name must be the name of a registered measure"):
            robust(bad, tolerances={"slider_radius": 1e-3})
    with pytest.raises(RobustError, match=r"^robust: name: unknown objective 'volumee'"):
        robust("volumee", tolerances={"slider_radius": 1e-3})
    with pytest.raises(RobustError, match=r"^mech must be a mechanism, e.g. parasynth.load_mechanism\('5pus_upu'\)"):
        by_name.evaluate("5pus_upu")
