"""The compiled feasibility engine (parasynth.engine, through parasynth.engine.kernels) against the
NumPy reference.

``feasible_fast(mech, X)`` (and ``mech.is_feasible(X)``, which uses the engine by default) must
return ``mech.is_feasible(X, engine="numpy")``. The kernel evaluates the same
conditions in float64 but not always in the same arithmetic form (an angle limit is tested
through sin/cos of the limit instead of arctan2, a distance limit on squares, libm's sin/cos
may differ from NumPy's by an ulp), so the contract -- documented in the module -- is: the
booleans agree exactly except at poses whose NumPy feasibility margin (the smallest of the
legs' reachability margins and the constraint margins) is within 1e-12 of zero.

Poses are drawn in boxes chosen so that every constraint of every model is the only violated
one for a good fraction of the samples (checked, so the comparison cannot pass vacuously),
with unreachable poses, poses where the parametrisation is undefined, NaN/inf poses and poses
placed on the feasibility boundary by bisection. Default and non-default parameter sets are
used. Without numba, ``feasible_fast`` falls back to ``is_feasible`` and the same tests check
that path (plus a subprocess that hides numba).
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import parasynth
from parasynth.engine import kernels
from parasynth.model.constraints import JointAngleLimit
from parasynth.model.legs import GEOM_TOL, PRS, PUS, RUS

TOL = 1e-12
D = np.deg2rad

# Parameters pinned explicitly (not taken from the model defaults, which may be recalibrated)
# so that the cases keep exercising every constraint.
P5 = dict(slider_radius=0.135, link_length=0.205, hinge_layout="scheme1", upu_base_z=-0.15, slider_min=0.085,
          slider_max=0.290, sphere_max=D(40), ujoint_max=D(40), link_diameter=0.008)
P2 = dict(a1=0.15, a2=0.075, a3=0.15, a4=0.075, b1=0.55, b2=0.35, b3=0.55, b4=0.35, q_min=0.7, q_max=1.0,
          psi_max=D(30), theta_max=D(45), leg_diameter=0.03)
P4 = dict(platform_radius=0.1, base_radius=0.335, l_s0=0.05, base_offset=0.0, l_min=0.43, l_max=0.68, d2_min=0.32,
          d2_max=0.55, theta1_max=np.pi / 3, sphere_max=np.pi / 4, ujoint_max=np.pi / 4, leg_diameter=0.035)
B5 = ([-0.1, -0.1, -0.16, -0.7, -0.7], [0.1, 0.1, 0.12, 0.7, 0.7])
B2 = ([0.5, -0.7, -0.95], [1.0, 0.7, 0.95])
B4 = ([-0.3, 0.2, -0.6, -0.1, -0.6], [0.3, 0.56, 0.6, 0.8, 0.6])

#: (case id, model, parameters, task box lo, hi). Each model runs with its default parameters
#: and with non-default sets; each constraint of a model is the sole violated one in >= 1% of
#: the samples of at least one of its cases (test_cases_exercise_every_constraint).
CASES = [
    ("5pus-default", "5pus_upu", {}, *B5),
    ("5pus-limits", "5pus_upu", P5, *B5),
    ("5pus-interference", "5pus_upu",
     {**P5, **dict(link_diameter=0.03, sphere_max=D(80), ujoint_max=D(80), slider_min=-0.2, slider_max=0.5)}, *B5),
    ("5pus-geometry", "5pus_upu",
     dict(slider_radius=0.14, link_length=0.21, hinge_layout="scheme2", hinge_rotation=0.1, hinge_scale=1.1,
          upu_base_z=-0.2, slider_min=0.09, slider_max=0.27, sphere_max=D(45), ujoint_max=D(30), link_diameter=0.02),
     *B5),
    ("5pus-pentagonal", "5pus_upu", {**P5, "platform": "pentagonal"}, *B5),
    ("2rpu-default", "2rpu_2sps", {}, *B2),
    ("2rpu-limits", "2rpu_2sps", P2, *B2),
    ("2rpu-theta", "2rpu_2sps", {**P2, **dict(theta_max=0.2, q_min=0.3, q_max=1.5)}, *B2),
    ("2rpu-interference", "2rpu_2sps",
     {**P2, **dict(a2=0.3, a4=0.3, b2=0.1, b4=0.1, leg_diameter=0.18, q_min=0.3, q_max=1.5)}, *B2),
    ("2rpu-uncoupled", "2rpu_2sps", {**P2, "coupled": False}, [-0.5, 0.55, -0.7, -0.95], [0.5, 1.0, 0.7, 0.95]),
    ("4ups-default", "4ups_1rps", {}, *B4),
    ("4ups-limits", "4ups_1rps", P4, [-0.3, 0.3, -0.6, -0.1, -0.6], [0.3, 0.56, 0.6, 0.6, 0.6]),
    ("4ups-theta1", "4ups_1rps",
     {**P4, **dict(l_min=0.2, l_max=1.0, d2_min=0.1, d2_max=1.0, sphere_max=1.2, ujoint_max=1.4, theta1_max=0.3)},
     *B4),
    ("4ups-ujoint", "4ups_1rps",
     {**P4, **dict(l_min=0.2, l_max=1.0, d2_min=0.1, d2_max=1.0, sphere_max=1.2, ujoint_max=0.7)}, *B4),
    ("4ups-interference", "4ups_1rps",
     {**P4, **dict(l_min=0.2, l_max=1.0, d2_min=0.1, d2_max=1.0, sphere_max=1.2, ujoint_max=1.4,
                   leg_diameter=0.138)}, *B4),
    ("4ups-centre", "4ups_1rps",
     {**P4, **dict(base_offset=-0.4, l_min=0.2, l_max=1.5, d2_min=0.1, d2_max=1.0, sphere_max=0.5, ujoint_max=1.4)},
     [-0.4, 0.2, -0.5, 0.0, -0.5], [0.4, 0.56, 0.5, 0.5, 0.5]),
]
CASE_IDS = [c[0] for c in CASES]
N_RANDOM = 20000

_MECHS: dict = {}


def _mech(name, params):
    key = (name, tuple(sorted(params.items())))
    if key not in _MECHS:
        _MECHS[key] = parasynth.load_mechanism(name, **params)
    return _MECHS[key]


def reach_margin(mech, X) -> np.ndarray:
    """The smallest of the legs' reachability margins (>= 0, or > 0 for a length, where the
    leg reaches): PUS discriminant L^2 - d_perp^2 (m^2); other legs: length (m), and for
    RPS/RPU the off-plane tolerance minus the off-plane error (m)."""
    X = np.asarray(X, dtype=float)
    valid = mech.pose_valid(X)
    Xs = np.where(valid[:, None], X, mech.home)
    p, R = mech.pose(Xs)
    reach = []
    states = [leg.solve(p, R) for leg in mech.legs]
    scale = max(1.0, max(float(np.max(st.length, initial=1.0)) for st in states))
    for leg, st in zip(mech.legs, states):
        if isinstance(leg, RUS):  # |K| <= hypot(P, Q) of RUS.solve, in m
            d = st.platform_point - leg.base
            h, L = leg.crank_length, leg.link_length
            K = (np.einsum("ij,ij->i", d, d) + h * h - L * L) / (2 * h)
            reach.append(np.hypot(d @ leg.crank_direction, d @ np.cross(leg.r_axis, leg.crank_direction)) - np.abs(K))
        elif isinstance(leg, (PUS, PRS)):
            d = st.platform_point - leg.base
            de = d @ leg.slider_axis
            reach.append(leg.link_length**2 - (np.einsum("ij,ij->i", d, d) - de**2))
            if isinstance(leg, PRS):
                reach.append(GEOM_TOL * max(1.0, leg.link_length) - st.extra["off_plane"])
        else:
            reach.append(st.length)
            if "off_plane" in st.extra:
                reach.append(GEOM_TOL * scale - st.extra["off_plane"])
            if "a4" in st.extra and hasattr(leg, "r_axis"):
                reach.append(GEOM_TOL - np.abs(st.extra["a4"] @ leg.r_axis))
    return np.min(np.stack(reach), axis=0)


def numpy_margin(mech, X) -> np.ndarray:
    """The NumPy feasibility margin of each pose: >= 0 iff ``is_feasible`` (up to the strict
    length > 0). The reachability margin and, where every leg reaches, the constraint
    margins. -inf where the parametrisation is undefined."""
    X = np.asarray(X, dtype=float)
    valid = mech.pose_valid(X)
    rm = reach_margin(mech, X)
    cm = np.min(np.stack(list(mech.constraint_margins(X, engine="numpy").values())), axis=0)
    reachable = mech.pose_context(X).reachable
    M = np.where(reachable, np.minimum(rm, cm), np.minimum(rm, 0.0))
    return np.where(valid, M, -np.inf)


def special_poses(mech, lo, hi) -> np.ndarray:
    """Home, NaN/inf poses, poses where the parametrisation is undefined, far unreachable
    poses and box corners."""
    n = mech.n_task
    rows = [mech.home, np.full(n, np.nan), np.where(np.arange(n) == 0, np.inf, mech.home),
            np.where(np.arange(n) == n - 1, -np.inf, mech.home), mech.home + 10.0, mech.home - 10.0,
            np.where(np.arange(n) == n - 1, 1e7, mech.home),  # sin/cos of a huge angle
            np.asarray(lo, float), np.asarray(hi, float)]
    if mech.name == "5pus_upu":  # the parametrisation's singular line x = 0, z = upu_base_z
        rows.append(np.array([0.0, 0.01, mech.params.upu_base_z, 0.1, 0.1]))
        rows.append(np.array([1e-7, 0.01, mech.params.upu_base_z, 0.1, 0.1]))
    if mech.name == "2rpu_2sps":  # theta = pi/2: x = z tan(theta) undefined
        X = mech.home.copy()
        X[mech.task_coordinates.index("theta")] = np.pi / 2
        rows.append(X)
    if mech.name == "4ups_1rps":  # platform centre at the origin: centre angle undefined
        rows.append(np.array([0.0, 0.0, 0.1, 0.1, 0.1]))
    return np.array(rows, dtype=float)


def boundary_poses(mech, X, n_pairs=300, iters=60) -> np.ndarray:
    """Poses on the feasibility boundary: bisection (on is_feasible) between feasible and
    infeasible samples; both final brackets are returned."""
    ok = mech.is_feasible(X, engine="numpy")
    fi, ii = np.flatnonzero(ok), np.flatnonzero(~ok & np.all(np.isfinite(X), 1))
    if fi.size == 0 or ii.size == 0:
        return np.zeros((0, X.shape[1]))
    rng = np.random.default_rng(11)
    a = X[rng.choice(fi, n_pairs)].copy()
    b = X[rng.choice(ii, n_pairs)].copy()
    # bring the infeasible end close first so the boundary found is a nearby one
    for _ in range(iters):
        m = 0.5 * (a + b)
        fm = mech.is_feasible(m, engine="numpy")
        a = np.where(fm[:, None], m, a)
        b = np.where(fm[:, None], b, m)
    return np.vstack([a, b])


def case_poses(mech, lo, hi, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(lo, hi, size=(N_RANDOM, mech.n_task))
    return np.vstack([X, special_poses(mech, lo, hi), boundary_poses(mech, X)])


def assert_agrees(mech, X, fast):
    ref = mech.is_feasible(X, engine="numpy")
    assert fast.dtype == np.bool_ and fast.shape == ref.shape
    diff = np.flatnonzero(fast != ref)
    if diff.size:
        M = numpy_margin(mech, X[diff])
        far = diff[~(np.abs(M) <= TOL)]
        assert far.size == 0, (
            f"{mech.name}: kernel and NumPy disagree at {far.size} poses away from the boundary, e.g. "
            f"X={X[far[0]].tolist()} numpy={ref[far[0]]} margin={numpy_margin(mech, X[far[:1]])[0]}")
    return ref, diff


@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_feasible_fast_matches_is_feasible(case):
    _, name, params, lo, hi = case
    mech = _mech(name, params)
    if kernels.HAVE_NUMBA:
        assert kernels.kernel_available(mech), f"{name} {params}: no kernel (model or constraints changed?)"
    X = case_poses(mech, lo, hi)
    ref, diff = assert_agrees(mech, X, kernels.feasible_fast(mech, X))
    if params:  # tuned cases: both outcomes well represented
        assert 0.005 < ref[:N_RANDOM].mean() < 0.995
    # random poses are (almost surely) not within 1e-12 of a boundary: no disagreement there
    assert not np.any(diff < N_RANDOM)
    # single pose -> scalar, like is_feasible
    for x in X[:3]:
        assert kernels.feasible_fast(mech, x) == mech.is_feasible(x, engine="numpy")
    # the default path of is_feasible is the engine's
    assert np.array_equal(mech.is_feasible(X), kernels.feasible_fast(mech, X))


@pytest.mark.parametrize("name", ["5pus_upu", "2rpu_2sps", "4ups_1rps"])
def test_cases_exercise_every_constraint(name):
    """Every constraint is the only violated one at >= 1% of the random samples of some case
    of its model; some poses are unreachable (5pus_upu) -- so the agreement tests are not
    vacuous."""
    sole = {}
    unreachable = 0.0
    for _, n, params, lo, hi in CASES:
        if n != name:
            continue
        mech = _mech(n, params)
        X = np.random.default_rng(0).uniform(lo, hi, size=(N_RANDOM, mech.n_task))
        ctx = mech.pose_context(X)
        unreachable = max(unreachable, 1 - ctx.reachable.mean())
        mg = mech.constraint_margins(X, engine="numpy")
        V = np.stack([m < 0 for m in mg.values()], 1) & ctx.reachable[:, None]
        only = V & (V.sum(1) == 1)[:, None]
        for j, c in enumerate(mg):
            sole[c] = max(sole.get(c, 0.0), only[:, j].mean())
    assert set(sole) == set(_mech(name, {}).constraints)
    weak = {c: f for c, f in sole.items() if f < 0.01}
    assert not weak, f"{name}: constraints rarely decisive in the test cases: {weak}"
    if name == "5pus_upu":
        assert unreachable > 0.02


@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_margins_fast_matches_constraint_margins(case):
    _, name, params, lo, hi = case
    mech = _mech(name, params)
    X = case_poses(mech, lo, hi, seed=1)
    ref = mech.constraint_margins(X, engine="numpy")
    fast = kernels.margins_fast(mech, X)
    assert list(fast) == list(ref)
    for c in ref:
        a, b = ref[c], fast[c]
        # unreachable (-inf) on both sides, except at the reachability boundary
        odd = np.flatnonzero(np.isneginf(a) != np.isneginf(b))
        assert np.all(np.abs(reach_margin(mech, X[odd])) <= TOL), (c, X[odd[:3]].tolist())
        assert not np.any(odd < N_RANDOM)
        fin = np.isfinite(a) & np.isfinite(b)
        assert np.array_equal(fin, np.isfinite(a) & ~np.isin(np.arange(len(a)), odd)), c
        # Rounding differences are amplified by arccos near 0 and pi (an ulp of the cosine is
        # ~1e-8 rad) and, at a PUS leg's reach limit, by the square root of its discriminant.
        tol = np.full(len(a), 1e-7 if mech.constraints[c].unit == "rad" else 1e-12)
        tol[np.abs(reach_margin(mech, X)) <= 1e-12] = 1e-6
        np.testing.assert_array_less(np.abs(b[fin] - a[fin]), tol[fin] * (1 + 1e-9), err_msg=c)


def test_parameters_are_read_from_the_mechanism():
    """The same poses under changed parameters give different answers, each the reference's."""
    lo, hi = [-0.08, -0.08, -0.12, -0.6, -0.6], [0.08, 0.08, 0.08, 0.6, 0.6]
    X = np.random.default_rng(5).uniform(lo, hi, size=(20000, 5))
    base = parasynth.load_mechanism("5pus_upu", **P5)
    r0 = kernels.feasible_fast(base, X)
    for change in (dict(slider_max=0.25), dict(sphere_max=D(30)), dict(ujoint_max=D(25)), dict(link_diameter=0.03),
                   dict(link_length=0.2), dict(slider_radius=0.13), dict(hinge_layout="scheme2"),
                   dict(upu_base_z=-0.05), dict(hinge_rotation=0.2)):
        mech = base.with_params(**change)
        r = kernels.feasible_fast(mech, X)
        assert not np.array_equal(r, r0), change
        assert_agrees(mech, X, r)


def test_unsupported_constraint_falls_back():
    mech = parasynth.load_mechanism("5pus_upu")
    extra = JointAngleLimit("u1", key="U_base_1", lo=-0.3, hi=0.3, legs=("L1",))
    mech.constraints["u1"] = extra
    assert not kernels.kernel_available(mech)
    X = np.random.default_rng(2).uniform([-0.08, -0.08, -0.12, -0.6, -0.6], [0.08, 0.08, 0.08, 0.6, 0.6], (3000, 5))
    assert np.array_equal(kernels.feasible_fast(mech, X), mech.is_feasible(X, engine="numpy"))
    del mech.constraints["u1"]
    assert kernels.kernel_available(mech) == kernels.HAVE_NUMBA


def test_unknown_model_and_changed_parametrisation_fall_back():
    """A subclass that changes the parametrisation, or a pose method replaced on an instance,
    is detected (the compiled pose is compared with mech.pose) and evaluated with NumPy."""
    base = parasynth.load_mechanism("5pus_upu")
    cls = type(base)

    class Variant(cls):  # a subclass may change anything: its pose is checked
        def _pose(self, X):
            p, R = super()._pose(X)
            return p + 0.001, R

    X = np.random.default_rng(3).uniform([-0.08, -0.08, -0.12, -0.6, -0.6], [0.08, 0.08, 0.08, 0.6, 0.6], (2000, 5))
    v = Variant(base.params)
    assert not kernels.kernel_available(v)
    assert np.array_equal(kernels.feasible_fast(v, X), v.is_feasible(X, engine="numpy"))

    m = parasynth.load_mechanism("5pus_upu")
    orig = m._pose

    def swapped(Xa):
        p, R = orig(Xa)
        return p, np.swapaxes(R, 1, 2)

    m._pose = swapped
    assert not kernels.kernel_available(m)
    assert np.array_equal(kernels.feasible_fast(m, X), m.is_feasible(X, engine="numpy"))


@pytest.mark.parametrize("case", CASES[::3], ids=CASE_IDS[::3])
def test_fallback_path_equals_is_feasible(case, monkeypatch):
    """With the kernel unavailable (as without numba) the results are is_feasible's and
    constraint_margins' exactly."""
    _, name, params, lo, hi = case
    mech = _mech(name, params)
    monkeypatch.setattr(kernels, "HAVE_NUMBA", False)
    assert not kernels.kernel_available(mech)
    X = case_poses(mech, lo, hi, seed=2)
    assert np.array_equal(kernels.feasible_fast(mech, X), mech.is_feasible(X, engine="numpy"))
    ref, fast = mech.constraint_margins(X, engine="numpy"), kernels.margins_fast(mech, X)
    assert all(np.array_equal(ref[c], fast[c]) for c in ref)


def test_without_numba_importable():
    """A process in which numba cannot be imported falls back silently."""
    code = (
        "import sys; sys.modules['numba'] = None\n"
        "import numpy as np, parasynth\n"
        "from parasynth import kernels\n"
        "assert not kernels.HAVE_NUMBA\n"
        "for name in parasynth.list_mechanisms():\n"
        "    m = parasynth.load_mechanism(name)\n"
        "    X = m.home + np.random.default_rng(0).uniform(-0.1, 0.1, (500, m.n_task))\n"
        "    assert not kernels.kernel_available(m)\n"
        "    assert np.array_equal(kernels.feasible_fast(m, X), m.is_feasible(X, engine='numpy'))\n"
        "    assert np.array_equal(m.is_feasible(X), m.is_feasible(X, engine='numpy'))\n"
        "print('ok')\n"
    )
    env = dict(os.environ)
    env.pop("PARASYNTH_NO_NUMBA", None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().endswith("ok")


def test_bad_input_is_reported_like_is_feasible():
    mech = _mech("5pus_upu", {})
    for bad in (np.zeros((4, 3)), np.zeros((2, 2, 5))):
        with pytest.raises(ValueError):
            mech.is_feasible(bad)
        with pytest.raises(ValueError):
            kernels.feasible_fast(mech, bad)
    assert kernels.feasible_fast(mech, np.zeros((0, 5))).shape == (0,)
