"""task.solve: dependent pose coordinates solved on the legs' closure equations
(model/parasitic.py, the description's task.solve), checked against the closed forms of the
shipped 3-RPS and 3-PRS, finite differences and bad input."""

import copy
import re
import warnings

import numpy as np
import pytest
import yaml

from parasynth import load_mechanism
from parasynth.mechanisms import described_class
from parasynth.mechanisms.description import DescriptionError
from parasynth.model.parasitic import closure_residuals, gauss_newton, implicit_gradient
from parasynth.mechanisms import _PACKAGE_DIR


def _solved(name):
    """The shipped description ``name`` with its closed-form parasitic motion replaced by
    task.solve (x, y, gamma unknowns)."""
    d = yaml.safe_load((_PACKAGE_DIR / f"{name}.yaml").read_text())
    t = d["task"]
    t.pop("define")
    t["solve"] = {"unknowns": {"x": "length", "y": "length", "gamma": "angle"}, "closure": "legs"}
    t["position"] = ["x", "y", "z"]
    d["name"] = f"{name}_solved"
    return d


def _poses(mech, n, seed):
    lo, hi = (np.array(v) for v in zip(*[mech.default_ranges()[k] for k in mech.task_coordinates]))
    rng = np.random.default_rng(seed)
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    return mid + 0.8 * half * rng.uniform(-1, 1, (n, len(lo)))


@pytest.mark.parametrize("name", ["3rps", "3prs"])
def test_solved_motion_matches_closed_form(name):
    """gamma = -atan2(sin a sin b, cos a + cos b), x = a/2 (R11 - R22), y = -a R21 (the shipped
    descriptions' closed forms) against the Gauss-Newton solve, to 1e-9."""
    ref = load_mechanism(name)
    cls = described_class(_solved(name), source=name)
    m = cls()
    X = _poses(ref, 64, 3)
    p0, R0 = ref._pose(X)
    p1, R1 = m._pose(X)
    ok = np.all(np.isfinite(p1), axis=1)
    assert ok.mean() > 0.95
    assert np.max(np.abs(p1[ok] - p0[ok])) < 1e-9
    assert np.max(np.abs(R1[ok] - R0[ok])) < 1e-9
    # the twist map through the implicit function theorem against the closed form's derivatives
    T0, T1 = ref._twist_map(X[ok]), m._twist_map(X[ok])
    assert np.max(np.abs(T1 - T0)) < 1e-6
    U = m.solved_unknowns(X[ok])
    a = ref.params.platform_radius
    assert np.allclose(U[:, 0], a / 2 * (R0[ok, 0, 0] - R0[ok, 1, 1]), atol=1e-10)
    assert np.allclose(U[:, 2], -np.arctan2(np.sin(X[ok, 1]) * np.sin(X[ok, 2]),
                                            np.cos(X[ok, 1]) + np.cos(X[ok, 2])), atol=1e-10)


def test_solved_mechanism_measures_match():
    """Mobility, inverse kinematics, singularity margin and feasibility on the solved 3-RPS equal
    the closed-form model's, on the compiled engine (no fallback) and on the NumPy path."""
    ref = load_mechanism("3rps")
    m = described_class(_solved("3rps"), source="3rps")()
    mob = m.mobility(warn=False)
    assert (mob.dof, mob.type, mob.controlled, mob.consistent) == (3, "1T2R", True, True)
    X = _poses(ref, 40, 5)
    assert np.allclose(m.inverse_kinematics(X).actuators, ref.inverse_kinematics(X).actuators, atol=1e-9, equal_nan=True)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        f1 = m.is_feasible(X)
        s1 = m.singularity_margin(X)
    assert not w, [str(x.message) for x in w]
    assert np.array_equal(f1, ref.is_feasible(X, engine="numpy"))
    assert np.array_equal(m.is_feasible(X, engine="numpy"), f1)
    assert np.allclose(s1, ref.singularity_margin(X, engine="numpy"), atol=1e-9)
    assert np.allclose(m.singularity_margin(X, engine="numpy"), s1, atol=1e-9)


def test_compiled_solve_matches_the_reference():
    """The unrolled solve of the pose program against the NumPy Gauss-Newton: validity, pose
    and twist map (implicit function theorem) on 3000 poses, over the shipped ranges and beyond."""
    from parasynth import engine
    m = described_class(_solved("3rps"), source="3rps")()
    rng = np.random.default_rng(8)
    X = np.column_stack([rng.uniform(0.2, 0.8, 3000), rng.uniform(-0.8, 0.8, 3000), rng.uniform(-0.8, 0.8, 3000)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        v, p, R, T = engine.pose_batch(m, X, twist=True)
    v0 = m.pose_valid(X)
    assert np.array_equal(v, v0)
    p0, R0 = m._pose(X[v])
    T0 = m._twist_map(X[v])
    assert np.max(np.abs(p[v] - p0)) < 1e-11 and np.max(np.abs(R[v] - R0)) < 1e-11
    assert np.max(np.abs(T[v] - T0)) < 1e-9


def test_gauss_newton_closed_form_and_failure():
    """A circle-line intersection (closed form) and a system without a solution (NaN)."""
    def fun(X, U):  # x^2 + y^2 = r^2, y = c:  U = (x, y)
        return np.stack([U[:, 0] ** 2 + U[:, 1] ** 2 - X[:, 0] ** 2, U[:, 1] - X[:, 1]], -1)
    X = np.array([[2.0, 1.0], [5.0, -3.0], [1.0, 2.0]])
    U, ok = gauss_newton(fun, X, np.array([1.0, 0.0]), np.ones(2))
    assert list(ok) == [True, True, False]
    assert np.allclose(U[:2, 0], np.sqrt(X[:2, 0] ** 2 - X[:2, 1] ** 2), atol=1e-12)
    assert np.all(np.isnan(U[2]))
    G = implicit_gradient(fun, X[:2], U[:2], np.ones(2), np.ones(2))
    # dx/dr = r/x, dx/dc = -c/x
    assert np.allclose(G[:, 0, 0], X[:2, 0] / U[:2, 0], atol=1e-7)
    assert np.allclose(G[:, 0, 1], -X[:2, 1] / U[:2, 0], atol=1e-7)


def test_closure_residuals_vanish_where_legs_reach():
    """The closure equations vanish exactly where the leg models' inverse kinematics says the
    legs reach (RPS plane, RPU plane and axis), and not elsewhere."""
    ref = load_mechanism("3rps")
    X = _poses(ref, 20, 9)
    p, R = ref._pose(X)
    assert np.max(np.abs(closure_residuals(ref.legs, p, R, ref.length_scale))) < 1e-12
    F = closure_residuals(ref.legs, p + [0.01, 0.0, 0.0], R, ref.length_scale)
    assert np.all(np.max(np.abs(F), axis=1) > 1e-4)
    an = load_mechanism("2rpu_2sps")
    Xa = an.home[None, :]
    pa, Ra = an._pose(Xa)
    assert np.max(np.abs(closure_residuals(an.legs, pa, Ra, an.length_scale))) < 1e-12
    assert closure_residuals(an.legs, pa, Ra, 1.0).shape == (1, 4)


def test_unreachable_pose_is_invalid():
    m = described_class(_solved("3rps"), source="3rps")()
    X = np.array([[0.5, 0.1, 0.1], [0.5, 3.0, 3.0], [np.nan, 0.0, 0.0]])
    v = m.pose_valid(X)
    assert v[0] and not v[2]


@pytest.mark.parametrize("edit, message", [
    (lambda t: t["solve"].update(unknowns={"z": "length"}), "task.solve.unknowns.z"),
    (lambda t: t["solve"].update(unknowns={"x": "mass"}), "kind must be length or angle"),
    (lambda t: t["solve"].update(unknowns={}), "task.solve.unknowns: give a mapping"),
    (lambda t: t["solve"].update(closure="equations"), "task.solve.closure: 'equations' is not allowed; allowed: legs"),
    (lambda t: t["solve"].update(start={"q": "0 mm"}), "task.solve.start.q: not an unknown"),
    (lambda t: t["solve"].update(extra=1), "task.solve"),
    (lambda t: (t["solve"].update(unknowns={"x": "length", "y": "length", "gamma": "angle", "q": "length"}),
                t.update(position=["x + 0*q", "y", "z"])),
     "task.solve.unknowns: 4 unknowns (x, y, gamma, q) but the legs give 3 closure equation(s); allowed: at most 3"),
    (lambda t: (t["solve"].update(unknowns={"x": "length", "y": "length", "q": "length"}),
                t.update(position=["x + 0*q", "y", "z"]),
                t["orientation"].update(angles=["alpha", "beta", "-atan2(sin(alpha)*sin(beta), cos(alpha) + cos(beta))"])),
     "task.solve.unknowns: the closure equations fix only 2 of the 3 unknowns"),
    (lambda t: t["solve"].update(start={"x": "2000 mm"}, unknowns={"x": "length", "y": "length", "gamma": "angle"}),
     None),
])
def test_bad_solve_input(edit, message):
    d = _solved("3rps")
    edit(d["task"])
    if message is None:  # a far start still converges to the home solution or says why
        try:
            m = described_class(copy.deepcopy(d), source="t")()
        except DescriptionError as e:
            assert "task.solve" in str(e)
        else:
            assert np.isfinite(m.solved_unknowns(m.home[None])).all()
        return
    with pytest.raises(DescriptionError, match=re.escape(message)):
        described_class(d, source="t")()
