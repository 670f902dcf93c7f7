"""Generic mechanism behaviour on every built-in model (parasynth.model.mechanism).

* the actuator Jacobian against central differences of the inverse kinematics;
* ``twist_map`` against finite differences of ``pose`` (v from dp, omega from dR R^T);
* inverse -> forward kinematics round trips (hypothesis);
* invariance of actuator values, Jacobian and singularity margin under a rigid displacement
  of the whole machine (base anchors, base-fixed axes and platform pose);
* the feasible twists of each parametrisation do no work against the constraint wrenches
  (checked where the model's parametrisation is exact, see the 5-PUS/UPU note below);
* forward kinematics errors.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import parasynth
from _support import (
                      MODEL_CONFIGS,
                      MODEL_IDS,
                      central_difference,
                      centre,
                      fd_steps,
                      load,
                      random_rotation,
                      sample_poses,
                      spread,
                      vee,
                      )
from parasynth.model.mechanism import Mechanism

configs = pytest.mark.parametrize("config", MODEL_CONFIGS, ids=MODEL_IDS)


def _mech(config):
    return load(*config)


# ---------------------------------------------------------------------------------------------
# Basic API shapes
# ---------------------------------------------------------------------------------------------


@configs
def test_api_shapes_single_and_batched(config):
    m = _mech(config)
    n, na = m.n_task, len(m.actuators)
    assert len(m.task_coordinates) == n and m.home.shape == (n,)
    assert dataclasses.is_dataclass(m.params)
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(m.params, dataclasses.fields(m.params)[0].name, 1.0)
    X = sample_poses(m, np.random.default_rng(0), 4)
    ik = m.inverse_kinematics(X)
    assert ik.actuators.shape == (4, na) and ik.reachable.shape == (4,)
    assert all(v.shape == (4,) for v in ik.passive_angles.values())
    assert m.jacobian(X).shape == (4, na, n)
    W = m.wrench_matrix(X)
    assert W.ndim == 3 and W.shape[0] == 4 and W.shape[2] == 6 and W.shape[1] >= na
    assert m.singularity_margin(X).shape == (4,)
    assert m.twist_map(X).shape == (4, 6, n)
    # a single pose (n,) gives unbatched results equal to the batched row
    ik1 = m.inverse_kinematics(X[1])
    assert ik1.actuators.shape == (na,)
    assert bool(ik1.reachable) == bool(ik.reachable[1])
    np.testing.assert_array_equal(ik1.actuators, ik.actuators[1])
    np.testing.assert_array_equal(m.jacobian(X[1]), m.jacobian(X)[1])
    assert np.ndim(m.singularity_margin(X[1])) == 0


# ---------------------------------------------------------------------------------------------
# Jacobian and twist map against finite differences
# ---------------------------------------------------------------------------------------------


@configs
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_jacobian_matches_central_differences_of_ik(config, seed):
    m = _mech(config)
    X = sample_poses(m, np.random.default_rng(seed), 6)
    ik = m.inverse_kinematics(X)
    assume(np.all(ik.reachable))
    h = fd_steps(m)
    J_fd = central_difference(lambda Y: m.inverse_kinematics(Y).actuators, X, h)
    J = m.jacobian(X)
    assert np.all(np.isfinite(J_fd))
    np.testing.assert_allclose(J, J_fd, rtol=1e-6, atol=1e-8)


@configs
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_twist_map_matches_finite_differences_of_pose(config, seed):
    m = _mech(config)
    X = sample_poses(m, np.random.default_rng(seed), 6)
    h = fd_steps(m)
    dp = central_difference(lambda Y: m.pose(Y)[0], X, h)  # (N, 3, n)
    dR = central_difference(lambda Y: m.pose(Y)[1], X, h)  # (N, 3, 3, n)
    _, R = m.pose(X)
    omega = np.stack([vee(dR[..., j] @ np.swapaxes(R, -1, -2)) for j in range(m.n_task)], axis=-1)
    T = m.twist_map(X)
    np.testing.assert_allclose(T[:, :3], dp, atol=1e-8)
    np.testing.assert_allclose(T[:, 3:], omega, atol=1e-8)


@configs
def test_jacobian_is_actuation_wrench_power_on_twist_map(config):
    """The wrench rows are (f, m_P) and the twists (v_P, omega): the rate of a telescopic leg
    is then (unit force) . (twist), and of a slider the same divided by n . e. Checked
    against finite differences, so a swapped ordering or a wrong reference point fails."""
    m = _mech(config)
    X = sample_poses(m, np.random.default_rng(1), 5)
    W = m.wrench_matrix(X)[:, : len(m.actuators)]
    T = m.twist_map(X)
    J_fd = central_difference(lambda Y: m.inverse_kinematics(Y).actuators, X, fd_steps(m))
    P = W @ T  # power of each unit actuation wrench on each coordinate's twist
    # P_ij / J_ij is the per-leg transmission scale: the same for every coordinate of a leg.
    ik = m.inverse_kinematics(X)
    for i, (leg, st_) in enumerate(zip(m.actuated_legs, [s for lg, s in zip(m.legs, ik.legs) if lg.is_actuated])):
        if leg.actuator_kind == "slider":
            scale = st_.direction @ leg.slider_axis
        else:
            scale = np.ones(X.shape[0])
        np.testing.assert_allclose(P[:, i, :], scale[:, None] * J_fd[:, i, :], atol=1e-7)


# ---------------------------------------------------------------------------------------------
# Constraint wrenches against the feasible twists
# ---------------------------------------------------------------------------------------------

# Every model's parametrisation must be consistent with its legs' constraints: a constraint
# wrench does no work on any motion of the model (for the 5-PUS/UPU this is why its
# orientation follows the U-P-U limb rather than eq. (7) literally; see its docstring).
@configs
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_constraint_wrenches_do_no_work_on_feasible_twists(config, seed):
    m = _mech(config)
    X = sample_poses(m, np.random.default_rng(seed), 6)
    C = m.wrench_matrix(X)[:, len(m.actuators):]
    assert C.shape[1] > 0
    # The U-P-U constraint is a numerically computed null vector that can sit far from the
    # platform centre (large moment): compare against the size of its terms.
    T = m.twist_map(X)
    scale = 1 + np.abs(C).max(axis=(1, 2), keepdims=True) * np.abs(T).max(axis=(1, 2), keepdims=True)
    assert np.all(np.abs(C @ T) <= 1e-11 * scale), np.max(np.abs(C @ T) / scale)


@pytest.mark.parametrize("platform", ["rectangular", "pentagonal"])
def test_5pus_constraint_reciprocal_to_twists_at_reference_pose(platform):
    m = load("5pus_upu", {"platform": platform})
    C = m.wrench_matrix(m.home)[len(m.actuators):]
    np.testing.assert_allclose(C @ m.twist_map(m.home[None])[0], 0.0, atol=1e-12)


@configs
def test_mobility_twist_basis_is_reciprocal_to_constraints(config):
    m = _mech(config)
    mob = m.mobility()
    C = m.wrench_matrix(m.home)[len(m.actuators):]
    assert mob.twist_basis.shape == (mob.dof, 6)
    np.testing.assert_allclose(C @ mob.twist_basis.T, 0.0, atol=1e-10)
    assert mob.dof == 6 - mob.constraint_rank
    if len(mob.uncontrolled_twists):
        W = m.wrench_matrix(m.home)
        np.testing.assert_allclose(W @ mob.uncontrolled_twists.T, 0.0, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# Forward kinematics
# ---------------------------------------------------------------------------------------------


def _fixed(m, X):
    return {"gamma": float(X[m.task_coordinates.index("gamma")])} if m.name == "4ups_1rps" else None


def _free(m, fixed):
    return [i for i, c in enumerate(m.task_coordinates) if c not in (fixed or {})]


def _well_conditioned(m, X, fixed):
    J = m.jacobian(X)[..., _free(m, fixed)]
    s = np.linalg.svd(J, compute_uv=False)
    return s[..., -1] > 1e-3 * s[..., 0]


@configs
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(seed=st.integers(0, 2**32 - 1))
def test_ik_fk_round_trip(config, seed):
    m = _mech(config)
    rng = np.random.default_rng(seed)
    X = sample_poses(m, rng, 1)[0]
    ik = m.inverse_kinematics(X)
    assume(bool(ik.reachable))
    fixed = _fixed(m, X)
    assume(_well_conditioned(m, X, fixed))
    guess = X + 0.1 * spread(m) * rng.uniform(-1, 1, m.n_task)
    Xf = m.forward_kinematics(ik.actuators, guess=guess, fixed=fixed)
    assert Xf.shape == X.shape
    # only the assembly mode near the guess is accepted
    np.testing.assert_allclose(Xf, X, atol=1e-9)
    np.testing.assert_allclose(m.inverse_kinematics(Xf).actuators, ik.actuators, atol=1e-11)


@configs
def test_fk_batched_from_home(config):
    """A batch of poses close to the reference, solved from the default guess (home, or
    the sampling centre for the pentagonal scheme whose home is singular)."""
    m = _mech(config)
    rng = np.random.default_rng(3)
    X = sample_poses(m, rng, 40, scale=0.3)
    ik = m.inverse_kinematics(X)
    fixed_cols = {}
    if m.name == "4ups_1rps":
        X[:, 4] = 0.05  # one fixed gamma for the whole batch
        ik = m.inverse_kinematics(X)
        fixed_cols = {"gamma": 0.05}
    ok = ik.reachable & _well_conditioned(m, X, fixed_cols)
    assert ok.sum() >= 5
    X, q = X[ok][:5], ik.actuators[ok][:5]
    guess = None if np.allclose(centre(m), m.home) else centre(m)
    if m.name == "4ups_1rps":
        guess = m.home.copy()
        guess[3] = 0.1  # the z-y-z angles are degenerate at beta = 0 (home)
    Xf = m.forward_kinematics(q, guess=guess, fixed=fixed_cols or None)
    np.testing.assert_allclose(Xf, X, atol=1e-9)


def test_fk_rejects_actuators_of_an_uncoupled_pose_for_the_coupled_2rpu_model():
    coupled = load("2rpu_2sps", {})
    free = load("2rpu_2sps", {"coupled": False})
    z, psi, th = 0.75, 0.2, np.deg2rad(15.0)
    x = z * np.tan(th) + 0.02  # 20 mm off the paper's x = z tan(theta)
    q = free.inverse_kinematics(np.array([x, z, psi, th])).actuators
    assert np.all(np.isfinite(q))
    with pytest.raises(parasynth.ForwardKinematicsError):
        coupled.forward_kinematics(q, guess=np.array([z, psi, th]))
    # ... while the same model accepts the actuators of a coupled pose.
    q_ok = free.inverse_kinematics(np.array([z * np.tan(th), z, psi, th])).actuators
    np.testing.assert_allclose(coupled.forward_kinematics(q_ok), [z, psi, th], atol=1e-9)


def test_fk_under_actuated_model_needs_fixed():
    m = load("4ups_1rps", {})
    q = m.inverse_kinematics(m.home).actuators
    with pytest.raises(ValueError, match="fixed"):
        m.forward_kinematics(q)
    with pytest.raises(ValueError):
        m.forward_kinematics(q, fixed={"not_a_coordinate": 0.0})


@configs
def test_fk_bad_actuator_shape(config):
    m = _mech(config)
    with pytest.raises(ValueError):
        m.forward_kinematics(np.ones(len(m.actuators) + 1))


# ---------------------------------------------------------------------------------------------
# Rigid-motion invariance
# ---------------------------------------------------------------------------------------------

#: Leg fields expressed in the base frame (points and axes); everything else of a leg is in
#: the platform frame or a scalar.
BASE_FRAME_AXES = {
    "SPS": (),
    "UPS": ("u_axis",),
    "PUS": ("slider_axis", "u_axis"),
    "RPS": ("r_axis",),
    "RPU": ("r_axis",),
    "UPU": ("u_axis",),
}


class Displaced(Mechanism):
    """The same machine after a rigid displacement (Q, t) of everything: base anchors and
    base-fixed axes are moved, the platform pose becomes (Q p + t, Q R)."""

    def __init__(self, inner: Mechanism, Q: np.ndarray, t: np.ndarray):
        self.inner, self.Q, self.t = inner, Q, t
        self.name = inner.name
        self.task_coordinates = inner.task_coordinates
        self.angular_coordinates = inner.angular_coordinates
        legs = []
        for leg in inner.legs:
            kind = type(leg).joints
            changes = {"base": Q @ leg.base + t, "base_ref": Q @ leg.base_ref}
            for f in BASE_FRAME_AXES[kind]:
                changes[f] = Q @ getattr(leg, f)
            legs.append(dataclasses.replace(leg, **changes))
        super().__init__(inner.params, legs, inner.home, inner.length_scale)

    def _pose(self, X):
        p, R = self.inner.pose(X)
        return p @ self.Q.T + self.t, self.Q @ R

    def _twist_map(self, X):
        T = self.inner.twist_map(X)
        B = np.zeros((6, 6))
        B[:3, :3] = B[3:, 3:] = self.Q
        return B @ T

    def pose_valid(self, X):
        return self.inner.pose_valid(X)


@configs
@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_rigid_motion_invariance(config, seed):
    m = _mech(config)
    rng = np.random.default_rng(seed)
    Q = random_rotation(rng)
    t = rng.uniform(-1.0, 1.0, 3)
    d = Displaced(m, Q, t)
    X = sample_poses(m, rng, 5)
    X[0] = m.home  # includes the singular home of the pentagonal scheme
    ik, ikd = m.inverse_kinematics(X), d.inverse_kinematics(X)
    np.testing.assert_array_equal(ik.reachable, ikd.reachable)
    assert np.any(ik.reachable)
    np.testing.assert_allclose(ikd.actuators, ik.actuators, atol=1e-12)
    for k, v in ik.passive_angles.items():
        np.testing.assert_allclose(ikd.passive_angles[k], v, atol=1e-9, err_msg=k)
    np.testing.assert_allclose(d.jacobian(X), m.jacobian(X), atol=1e-10)
    np.testing.assert_allclose(d.singularity_margin(X), m.singularity_margin(X), atol=1e-10)
    # Wrench rows change frame: forces and moments about the moved reference point rotate.
    W, Wd = m.wrench_matrix(X), d.wrench_matrix(X)
    Wr = np.concatenate([W[..., :3] @ Q.T, W[..., 3:] @ Q.T], axis=-1)
    na = len(m.actuators)
    np.testing.assert_allclose(Wd[:, :na], Wr[:, :na], atol=1e-12)
    # constraint rows up to sign (a numerically computed reciprocal screw has no set sign)
    err = np.minimum(np.abs(Wd[:, na:] - Wr[:, na:]).max(-1), np.abs(Wd[:, na:] + Wr[:, na:]).max(-1))
    # relative: the U-P-U constraint is a numerically computed null vector whose moment can be
    # large (a force on a line far from the platform centre)
    assert np.all(err < 1e-9 * (1 + np.abs(Wr[:, na:]).max(-1)))
    mob, mobd = m.mobility(), d.mobility()
    assert (mob.dof, mob.type, mob.controlled, mob.constraint_rank) == (
        mobd.dof, mobd.type, mobd.controlled, mobd.constraint_rank)


@configs
def test_margin_invariant_under_change_of_base_frame_of_wrench_rows(config):
    """Rotating forces and moments of every row by one rotation (a change of the base frame)
    keeps the singular values that the margin is built from."""
    m = _mech(config)
    rng = np.random.default_rng(11)
    X = sample_poses(m, rng, 4)
    M = m.normalized_wrench_system(X)
    Q = random_rotation(rng)
    Mr = np.concatenate([M[..., :3] @ Q.T, M[..., 3:] @ Q.T], axis=-1)
    k = min(M.shape[1], 6)
    s = np.linalg.svd(Mr, compute_uv=False)[:, k - 1]
    np.testing.assert_allclose(m.singularity_margin(X), s, atol=1e-12)


def _controlled_near_one_at_a_time(mech, X0):
    """The check of ``Mechanism._controlled_near`` done pose by pose (one wrench matrix each)."""
    rng = np.random.default_rng(12345)
    step = np.where([c in mech.angular_coordinates for c in mech.task_coordinates], 0.05, 0.02 * mech.length_scale)
    for _ in range(5):
        W = mech.wrench_matrix((X0 + step * rng.uniform(-1, 1, size=X0.shape))[None, :])[0]
        if np.all(np.isfinite(W)):
            W = W.copy()
            W[:, 3:] /= mech.length_scale
            s = np.linalg.svd(W, compute_uv=False)
            if int(np.sum(s > 1e-8 * max(s[0], 1e-300))) == 6:
                return True
    return False


@pytest.mark.parametrize("name", ["3rps", "3prs", "4ups_1rps", "5pus_upu", "2rpu_2sps"])
def test_controlled_near_batched_equals_pose_by_pose(name):
    """The five perturbed poses of the controllability check evaluated in one batch answer as
    one at a time, at home and at poses off home (under-actuated 4ups_1rps: never controlled)."""
    import warnings

    from parasynth.mechanisms import load_mechanism

    mech = load_mechanism(name)
    rng = np.random.default_rng(7)
    span = np.where([c in mech.angular_coordinates for c in mech.task_coordinates], 0.1, 0.03 * mech.length_scale)
    answers = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(4):
            X0 = mech.home + (0 if k == 0 else span * rng.uniform(-1, 1, size=mech.home.shape))
            got = mech._controlled_near(X0)
            assert got == _controlled_near_one_at_a_time(mech, X0), (name, X0)
            answers.append(got)
    assert all(answers) == (name != "4ups_1rps") and any(answers) == (name != "4ups_1rps")
