"""The compiled engine (parasynth.engine) on every shipped mechanism and variant, and on
randomly generated descriptions, against the NumPy reference; its use by default and its
fallback with a stated reason.

The agreement contract is the one of ``tests/engine/test_kernels.py``: feasibility booleans agree
except at poses whose NumPy feasibility margin is within 1e-12 of zero; margins agree to
rounding (amplified by arccos near 0 and pi); poses, rotations and twist maps to rounding.
"""

from __future__ import annotations

import importlib
import math
import tracemalloc
import warnings

import numpy as np
import pytest

import parasynth
from parasynth import engine
from parasynth.engine import kernels
from parasynth.mechanisms.description import description_class
from _support import shipped_configs
from test_kernels import assert_agrees, boundary_poses, reach_margin

TOL = 1e-12
needs_numba = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not importable: the NumPy path is the engine")


def _box(mech, widen=1.0):
    r = mech.default_ranges()
    lo, hi = [], []
    for j, c in enumerate(mech.task_coordinates):
        if c in r:
            a, b = r[c]
        else:
            s = 0.5 if c in mech.angular_coordinates else 0.2 * mech.length_scale
            a, b = mech.home[j] - s, mech.home[j] + s
        m, h = 0.5 * (a + b), 0.5 * (b - a) * widen
        lo.append(m - h)
        hi.append(m + h)
    return np.array(lo), np.array(hi)


def check_mechanism(mech, n=6000, seed=0, lo=None, hi=None):
    """Feasibility, margins and poses of the compiled engine against NumPy on random poses in
    a box, NaN/inf poses and poses placed on the feasibility boundary."""
    if lo is None:
        lo, hi = _box(mech)
    rng = np.random.default_rng(seed)
    X = rng.uniform(lo, hi, size=(n, mech.n_task))
    special = np.array([mech.home, np.full(mech.n_task, np.nan), np.where(np.arange(mech.n_task) == 0, np.inf, mech.home),
                        mech.home + 10.0])
    Xb = boundary_poses(mech, X, n_pairs=100, iters=50)
    Xa = np.vstack([X, special, Xb])
    if engine.HAVE_NUMBA:
        assert engine.available(mech), engine.reason(mech)
    fast = engine.feasible(mech, Xa)
    ref, diff = assert_agrees(mech, Xa, fast)
    assert not np.any(diff < n), "random poses must agree exactly"
    # margins
    M0 = mech.constraint_margins(Xa, engine="numpy")
    M1 = engine.margins(mech, Xa)
    assert list(M0) == list(M1)
    rm = np.abs(reach_margin(mech, Xa))
    for c in M0:
        a, b = M0[c], M1[c]
        odd = np.flatnonzero(np.isneginf(a) != np.isneginf(b))
        assert np.all(rm[odd] <= TOL), (c, Xa[odd[:3]].tolist())
        fin = np.isfinite(a) & np.isfinite(b)
        assert np.array_equal(np.isposinf(a), np.isposinf(b)), c
        unit = mech.constraints[c].unit
        tol = np.full(len(a), 1e-7 if unit in ("rad", "1") else 1e-12)
        tol[rm <= 1e-12] = 1e-6
        np.testing.assert_array_less(np.abs(b[fin] - a[fin]), tol[fin] * (1 + np.abs(a[fin])), err_msg=c)
    # poses and twist maps
    valid0 = mech.pose_valid(X)
    v, p, R, T = engine.pose_batch(mech, X, twist=True)
    assert np.array_equal(v, valid0)
    p0, R0 = mech.pose(X[valid0])
    T0 = mech.twist_map(X[valid0])
    scale = max(1.0, float(np.abs(p0).max(initial=0)))
    np.testing.assert_allclose(p[valid0], p0, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(R[valid0], R0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(T[valid0], T0, rtol=0, atol=1e-9 * max(1.0, float(np.abs(T0).max(initial=0))))
    return ref[:n]


SHIPPED = shipped_configs()


@pytest.mark.parametrize("name,params", SHIPPED, ids=[f"{n}-{p}" if p else n for n, p in SHIPPED])
def test_every_shipped_mechanism_and_variant(name, params):
    mech = parasynth.load_mechanism(name, **params)
    ref = check_mechanism(mech)
    assert 0.0 < ref.mean() < 1.0  # both outcomes present: the comparison is not vacuous


# ---------------------------------------------------------------------------------------------
# randomly generated descriptions
# ---------------------------------------------------------------------------------------------
_CONVENTIONS = ["zyz", "yzx", "xyz", "zyx", "zxz", "yxy"]
_MARGINS = [
    ("hypot(px, py) * -1 + 0.06", "m"),
    ("min(lim - abs(alpha), lims[1] - abs(beta))", "rad"),
    ("R33 - cos(25 deg)", "1"),
    ("clip(pz - z_lo, -1, 1) + 0.002*tanh(x*10)", "m"),
    ("atan2(py, px + 1) + 0.05", "rad"),
    ("sqrt(px**2 + py**2 + 0.0001) - 0.02*exp(z) + max(R11, R22) - 0.9", "1"),
    ("log(1.5 + sin(alpha)*cos(beta)) + 0.004 - x**2 - 3*y**2", "1"),
    ("0.3 - abs(asin(clip(R13, -1, 1)))", "rad"),
    ("1 - acos(clip(R33, -1, 1)) - abs(gamma)/2", "rad"),
    ("0.6 - abs(tan(alpha)) + 0.1*cosh(beta) - 0.1 + 0.01*sinh(gamma) + 0.01*atan(x)", "1"),
    ("0.1 - abs(g2 - gamma) + 0.001*sign_free", "rad"),
]


def random_description(seed: int) -> dict:
    """A valid 6-DOF description built from the shipped leg types with random anchors, axes,
    leg types, orientation (an Euler convention or a rotations: list with numeric axes),
    defined coordinates, positions using R entries, validity conditions and constraints
    (including expression margins over the pose)."""
    rng = np.random.default_rng(seed)
    rb, rp, h = rng.uniform(0.3, 0.5), rng.uniform(0.12, 0.25), rng.uniform(0.45, 0.7)
    mm = lambda v: f"{v * 1e3:.6g} mm"  # noqa: E731
    base_ang = 2 * np.pi * np.arange(6) / 6 + rng.uniform(-0.3, 0.3, 6)
    plat_ang = base_ang + rng.uniform(-0.5, 0.5, 6)
    legs = []
    for k in range(6):
        t = str(rng.choice(["UPS", "SPS", "PUS", "UPU"]))
        b = [rb * math.cos(base_ang[k]), rb * math.sin(base_ang[k]), 0.0]
        a = [rp * math.cos(plat_ang[k]), rp * math.sin(plat_ang[k]), 0.0]
        leg = {"type": t, "name": f"L{k + 1}", "base": [mm(v) for v in b], "platform": [mm(v) for v in a],
               "actuated": "P"}
        if t in ("UPS", "UPU"):
            leg["u_axis"] = str(rng.choice(["x", "y"]))
        if t == "UPU":
            leg["u_platform_axis"] = str(rng.choice(["x", "y"]))
        if t == "PUS":
            dh = math.hypot(a[0] - b[0], a[1] - b[1])
            leg["slider_axis"] = "z"
            leg["u_axis"] = str(rng.choice(["x", "y"]))
            leg["link_length"] = mm(dh * rng.uniform(1.2, 1.8) + 0.05)
            leg["branch"] = int(rng.choice([-1, 1]))
        legs.append(leg)
    task = {"coordinates": {"x": "length", "y": "length", "z": "length", "alpha": "angle", "beta": "angle",
                            "gamma": "angle"},
            "define": {"g2": f"gamma + {rng.uniform(-0.3, 0.3):.4f}*sin(alpha)*beta",
                       "sign_free": "abs(x) + 1"},
            "home": {"x": "0 mm", "y": "0 mm", "z": mm(h), "alpha": "0 deg", "beta": "0 deg", "gamma": "0 deg"},
            "ranges": {"x": ["-120 mm", "120 mm"], "y": ["-120 mm", "120 mm"], "z": [mm(h - 0.15), mm(h + 0.15)],
                       "alpha": ["-30 deg", "30 deg"], "beta": ["-30 deg", "30 deg"], "gamma": ["-40 deg", "40 deg"]}}
    if rng.random() < 0.5:
        task["orientation"] = {"convention": str(rng.choice(_CONVENTIONS)), "angles": ["alpha", "beta", "g2"]}
    else:
        ax = rng.normal(size=3)
        task["orientation"] = {"rotations": [{"axis": [float(round(v, 3)) for v in ax], "angle": "alpha"},
                                             {"axis": str(rng.choice(["x", "y", "z"])), "angle": "beta"},
                                             {"axis": "z", "angle": "g2"}]}
    c = rng.uniform(-0.05, 0.05)
    task["position"] = ([f"x + {c:.4f}*R13", f"y - {c:.4f}*R23", "z"] if rng.random() < 0.5 else ["x", "y", "z"])
    if rng.random() < 0.5:
        task["valid"] = ["abs(cos(beta)) > 0.05", "-1.2 < alpha < 1.2"]
    margins = [_MARGINS[i] for i in rng.choice(len(_MARGINS), 2, replace=False)]
    cons = [{"name": "stroke", "type": "actuator_range", "min": "q_lo", "max": "q_hi"},
            {"name": "sphere", "type": "joint_angle", "key": "S_platform_cone", "max": f"{rng.uniform(25, 50):.3g} deg"},
            {"name": "ujoint", "type": "joint_angle", "key": "U_base_cone", "max": f"{rng.uniform(25, 50):.3g} deg"},
            {"name": "interference", "type": "interference", "diameter": "dia"},
            {"name": "axis", "type": "leg_axis_angle", "legs": ["L1", "L2"], "axis": "z", "frame": "base",
             "max": "axis_max"},
            {"name": "gamma_range", "type": "coordinate_range", "coordinate": "gamma", "min": "-35 deg", "max": "35 deg"}]
    for k, (text, unit) in enumerate(margins):
        cons.append({"name": f"expr{k}", "type": "expression", "margin": text, "unit": unit})
    return {"name": f"random_{seed}", "parameters": {"q_lo": "0 mm", "q_hi": "2000 mm", "lim": "25 deg",
                                                      "lims": ["20 deg", "28 deg"], "z_lo": mm(h - 0.1),
                                                      "dia": mm(rng.uniform(0.005, 0.04)),
                                                      "axis_max": f"{rng.uniform(30, 60):.3g} deg"},
            "base": {}, "platform": {}, "legs": legs, "task": task, "length_scale": mm(rb), "constraints": cons}


def _random_mechanism(seed):
    data = random_description(seed)
    mech = description_class(data)()
    # stroke limits around the actuator values at home so that they cut the workspace
    q = mech.inverse_kinematics(mech.home).actuators
    span = 0.08 + 0.1 * np.random.default_rng(seed).random()
    P = data["parameters"]
    P["q_lo"] = f"{(q.min() - span) * 1e3:.6g} mm"
    P["q_hi"] = f"{(q.max() + span) * 1e3:.6g} mm"
    # the leg-axis limit and the link diameter are made to hold at home with some room
    m = mech.constraint_margins(mech.home, engine="numpy")
    angle = mech.params.axis_max - m["axis"]
    P["axis_max"] = f"{math.degrees(max(mech.params.axis_max, angle + 0.1)):.6g} deg"
    dist = m["interference"] + mech.params.dia
    P["dia"] = f"{min(mech.params.dia, 0.6 * dist) * 1e3:.6g} mm"
    return description_class(data)()


@pytest.mark.parametrize("seed", range(10))
def test_random_descriptions(seed):
    try:
        mech = _random_mechanism(seed)
    except ValueError as e:  # a random draw that is not a valid description is redrawn
        pytest.fail(f"generator produced an invalid description: {e}")
    lo, hi = _box(mech, widen=0.6)
    ref = check_mechanism(mech, n=4000, seed=seed, lo=lo, hi=hi)
    assert 0.0 < ref.mean() < 1.0


def test_random_descriptions_cover_the_language():
    """The generator exercises both orientation forms, R entries in positions, validity
    conditions and every margin template."""
    seen = {"convention": 0, "rotations": 0, "R_in_position": 0, "valid": 0}
    margins = set()
    for seed in range(10):
        d = random_description(seed)
        t = d["task"]
        seen["convention" if "convention" in t["orientation"] else "rotations"] += 1
        seen["R_in_position"] += any("R" in p for p in t["position"])
        seen["valid"] += "valid" in t
        margins |= {c["margin"] for c in d["constraints"] if c["type"] == "expression"}
    assert all(v > 0 for v in seen.values()), seen
    assert len(margins) >= 8


# ---------------------------------------------------------------------------------------------
# default routing, explicit reference, fallback with a reason
# ---------------------------------------------------------------------------------------------
def test_engine_argument_is_validated():
    mech = parasynth.load_mechanism("3rps")
    X = mech.home[None, :]
    for bad in ("fast", None, 3):
        with pytest.raises(ValueError, match="engine"):
            mech.is_feasible(X, engine=bad)
        with pytest.raises(ValueError, match="engine"):
            parasynth.workspace(mech, n=64, engine=bad)
    assert np.array_equal(mech.is_feasible(X, engine="numpy"), mech._is_feasible_numpy(X))


def test_untranslatable_construct_falls_back_once_with_its_name():
    data = random_description(3)
    data["name"] = "indexes_a_coordinate"
    data["constraints"].append({"name": "odd", "type": "expression", "margin": "0.5 - abs(x[0])"})
    mech = description_class(data)()
    assert not engine.available(mech)
    assert "index into 'x'" in engine.reason(mech)
    X = np.random.default_rng(0).uniform(*_box(mech), size=(500, 6))
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        a = mech.is_feasible(X)
        b = mech.is_feasible(X)
    msgs = [str(x.message) for x in w if issubclass(x.category, engine.EngineFallbackWarning)]
    assert len(msgs) == 1 and "index into 'x'" in msgs[0] and "NumPy" in msgs[0]
    ref = mech.is_feasible(X, engine="numpy")
    assert np.array_equal(a, ref) and np.array_equal(b, ref)
    # other constraint selections without the odd one are compiled
    names = [c for c in mech.constraints if c != "odd"]
    assert engine.available(mech, names)
    np.testing.assert_array_equal(mech.is_feasible(X, names=names),
                                  mech.is_feasible(X, names=names, engine="numpy"))


@needs_numba
def test_parameters_change_without_new_program():
    """Parameter values are constants of one program per description: a changed design uses
    the same compiled program and gives the reference's answer."""
    from parasynth.engine import core

    m1 = parasynth.load_mechanism("3rps")
    m2 = m1.with_params(platform_radius=0.17, q_max=0.65)
    p1, p2 = engine.plan(m1)[0], engine.plan(m2)[0]
    assert p1.program is p2.program
    assert not np.array_equal(p1.consts, p2.consts)
    X = np.random.default_rng(1).uniform(*_box(m2), size=(4000, 3))
    assert_agrees(m2, X, m2.is_feasible(X))
    assert len(core._PROGRAMS) >= 1


# ---------------------------------------------------------------------------------------------
# workspaces
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["5pus_upu", "4ups_1rps", "3prs"])
def test_workspace_engines_agree(name):
    mech = parasynth.load_mechanism(name)
    a = parasynth.workspace(mech, n=2**13, engine="compiled")
    b = parasynth.workspace(mech, n=2**13, engine="numpy")
    assert a.n_feasible == b.n_feasible > 0
    assert np.array_equal(a.points, b.points)
    for ax in "xyz":
        np.testing.assert_allclose(a.extents[ax], b.extents[ax], rtol=0, atol=1e-12)


def test_samples_are_generated_once_and_reused():
    W = importlib.import_module("parasynth.workspace")

    mech = parasynth.load_mechanism("5pus_upu")
    W._SAMPLES.clear()
    a = parasynth.workspace(mech, n=5000, seed=3)
    assert len(W._SAMPLES.entries) == 1
    key = next(iter(W._SAMPLES.entries))
    chunks = W._SAMPLES.get(key)
    m2 = mech.with_params(link_length=0.21)
    b = parasynth.workspace(m2, n=5000, seed=3)
    assert len(W._SAMPLES.entries) == 1 and W._SAMPLES.get(key) is chunks  # reused
    assert all(not c[1].flags.writeable for c in chunks)
    # the cached points are the sampler's: same result as without the cache
    W._SAMPLES.clear()
    b2 = parasynth.workspace(m2, n=5000, seed=3)
    assert b.n_feasible == b2.n_feasible and np.array_equal(b.points, b2.points)
    assert a.n_feasible != b.n_feasible
    c = parasynth.workspace(mech, n=5000, seed=4)
    assert c.n_feasible != a.n_feasible or not np.array_equal(c.points, a.points)


def test_large_workspace_memory_is_bounded():
    """Beyond the sample cache, samples stream chunk by chunk: the traced peak does not grow
    with n (here 2.2e6 samples, keep_points=False)."""
    W = importlib.import_module("parasynth.workspace")

    mech = parasynth.load_mechanism("3rps")
    n = W.SAMPLE_CACHE_MAX_POINTS + 2**17
    parasynth.workspace(mech, n=4096)
    tracemalloc.start()
    try:
        ws = parasynth.workspace(mech, n=n, keep_points=False, progress=False)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert ws.n_samples == n
    assert peak < 64 * 2**20, peak / 2**20


# ---------------------------------------------------------------------------------------------
# studies
# ---------------------------------------------------------------------------------------------
def test_study_engine_setting_reaches_the_measures():
    from parasynth.study.evaluate import Evaluator
    from parasynth.study.spec import StudyError, load_study

    text = """
name: engine_check
mechanism: 3rps
variables:
  - {name: platform_radius, values: [150 mm]}
objectives:
  - {name: workspace_volume, goal: maximize}
evaluation: {samples: 2048, engine: ENGINE}
"""
    vols = {}
    for eng in ("compiled", "numpy"):
        st = load_study(text.replace("ENGINE", eng), is_text=True)
        assert st.evaluation["engine"] == eng
        ev = Evaluator(st)
        assert ev.settings_for("workspace_volume", {})["engine"] == eng
        rec = ev.evaluate({"platform_radius": 0.15})
        assert rec.status == "ok", rec.error
        vols[eng] = rec.objectives["workspace_volume"]
    assert vols["compiled"] == vols["numpy"] > 0
    with pytest.raises((StudyError, ValueError), match="evaluation.engine"):
        load_study(text.replace("ENGINE", "fast"), is_text=True)


def test_kernels_module_names():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    assert kernels.kernel_available(mech) == kernels.HAVE_NUMBA
    X = np.random.default_rng(0).uniform(*_box(mech), size=(1000, 6))
    np.testing.assert_array_equal(kernels.feasible_fast(mech, X), mech.is_feasible(X))


def test_huge_coordinates_follow_the_numpy_path():
    """Where the NumPy path treats a coordinate beyond MAX_POSE_MAGNITUDE as unreachable (here a
    subclass masking it in pose_valid), the compiled path does too; where it does not, a
    whole number of turns past it is the home pose again for both."""
    from parasynth.common.validation import MAX_POSE_MAGNITUDE

    base = parasynth.load_mechanism("gough_stewart_6ups")

    class Masking(type(base)):
        def pose_valid(self, X):
            return super().pose_valid(X) & np.all(np.abs(X) <= MAX_POSE_MAGNITUDE, axis=-1)

    turns = 2 * np.pi * math.ceil(2 * MAX_POSE_MAGNITUDE / (2 * np.pi))
    for mech, expect in ((Masking(base.params), False), (base, True)):
        X = np.array([mech.home, mech.home])
        X[1, 3] += turns
        ref = mech.is_feasible(X, engine="numpy")
        assert ref.tolist() == [True, expect]
        assert mech.is_feasible(X).tolist() == ref.tolist()
        assert engine.pose_batch(mech, X)[0].tolist() == mech.pose_valid(X).tolist()
