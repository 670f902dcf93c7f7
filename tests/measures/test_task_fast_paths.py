"""The faster forms inside the task evaluation against the general ones they replace: the
SPS/UPS wrench system of all legs at once against the legs' own methods one leg at a time, the
payload's equivalent load against ``parasynth.measures.dynamics.equivalent_load``, the path's
rates computed on first read against finite differences of the path, and the cache of
mechanism-independent work that a task's copies share (it must never hand one task another's
poses or path)."""

from __future__ import annotations

import numpy as np
import pytest

import parasynth
from parasynth.measures import dynamics
from parasynth.measures.indices import wrench_system
from parasynth.measures.task import _line_legs, _payload_load, _wrench_system, task_evaluation
from parasynth.model.task import Payload, Task

G = 9.80665


@pytest.fixture(scope="module")
def gs():
    return parasynth.load_mechanism("gough_stewart_6ups")


def _poses(n, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-0.15, 0.15, (n, 2)), rng.uniform(0.4, 0.95, n),
                            rng.uniform(-0.3, 0.3, (n, 3))])


def test_line_wrench_system_equals_the_legs_one_at_a_time(gs):
    assert _line_legs(gs) is not None
    X = _poses(300)
    X[7, 0] = np.nan  # an invalid pose: NaN rows in both
    fast, ref = _wrench_system(gs, X), wrench_system(gs, X)
    np.testing.assert_array_equal(fast.reachable, ref.reachable)
    assert not fast.reachable[7] and fast.reachable.sum() == 299
    for name in ("actuation", "rate_scale", "anchors"):
        a, b = getattr(fast, name), getattr(ref, name)
        assert a.shape == b.shape
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
        np.testing.assert_allclose(a[fast.reachable], b[ref.reachable], rtol=0, atol=1e-14)
    assert fast.constraint.shape == (300, 0, 6)
    # the actuation rows are unit forces along the legs: |f| = 1 and f . m = 0 (a pure line)
    act = fast.actuation[fast.reachable]
    np.testing.assert_allclose(np.linalg.norm(act[..., :3], axis=-1), 1.0, atol=1e-14)
    np.testing.assert_allclose(np.sum(act[..., :3] * act[..., 3:], axis=-1), 0.0, atol=1e-14)


def test_other_leg_types_keep_the_general_wrench_system():
    mech = parasynth.load_mechanism("5pus_upu")
    assert _line_legs(mech) is None


def test_payload_load_equals_the_equivalent_load(gs):
    rng = np.random.default_rng(3)
    X = _poses(50, seed=3)
    Xd, Xdd = rng.normal(size=X.shape), rng.normal(size=X.shape)
    m, com = 7.5, np.array([0.01, -0.02, 0.05])
    I = np.array([[0.2, 0.01, -0.02], [0.01, 0.3, 0.0], [-0.02, 0.0, 0.25]])
    inertia = parasynth.InertiaModel(dynamics.PlatformInertia(m, com, I))
    g = np.array([0.0, 0.0, -G])
    ref = dynamics.equivalent_load(gs, X, Xd, Xdd, inertia, gravity=g)
    Xa, _, ok, ws, p, R, t, acc, legs = dynamics._motion(gs, X, Xd, Xdd, inertia)
    assert legs == []
    got = _payload_load(Payload(m, tuple(com), I), ok, R, t, acc, g)
    np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-12)
    # at rest the load is the weight and its moment about P, by hand
    z = np.zeros_like(t)
    rest = _payload_load(Payload(m, tuple(com), I), ok, R, z, z, g)
    rc = R @ com
    np.testing.assert_allclose(rest[:, :3], np.broadcast_to(m * g, (50, 3)), atol=1e-12)
    np.testing.assert_allclose(rest[:, 3:], np.cross(rc, m * g), atol=1e-12)


def _named_task(**kw):
    X = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.08, 0.02, 0.03, 0.1, -0.05, 0.2],
                  [-0.05, 0.06, -0.02, -0.1, 0.05, -0.2]])
    return Task(X, coordinates=("x", "y", "z", "alpha", "beta", "gamma"), placement={"offset": (0, 0, 0.62)},
                tool=(0.0, 0.0, 0.05), trajectory={"speed": 0.2, "acceleration": 1.0, "angular_speed": 1.0,
                                                   "angular_acceleration": 4.0, "jerk_time": 0.02, "dt": 0.005}, **kw)


def test_rates_read_on_demand_are_the_paths_finite_differences(gs):
    path = _named_task().path(gs)
    X, t = path.X, path.t
    dt = np.diff(t)
    # differences in time of X against the rates at the midpoints: within 1 % of their range
    # (the midpoint rule's error where the jerk ramps), while a wrong factor would be O(1)
    sd, sdd = np.max(np.abs(path.Xd), axis=0), np.max(np.abs(path.Xdd), axis=0)
    assert np.all(sd[[0, 1, 2, 5]] > 0.01) and np.all(sdd[[0, 1, 2, 5]] > 0.1)
    assert np.all(np.abs(np.diff(X, axis=0) / dt[:, None] - 0.5 * (path.Xd[1:] + path.Xd[:-1])) <= 0.01 * sd + 1e-9)
    assert np.all(np.abs(np.diff(path.Xd, axis=0) / dt[:, None] - 0.5 * (path.Xdd[1:] + path.Xdd[:-1]))
                  <= 0.05 * sdd + 1e-9)
    # the twist's translation is the time derivative of the platform point (x, y, z here)
    np.testing.assert_allclose(path.twist[:, :3], path.Xd[:, :3], atol=1e-6)


def test_copies_share_mechanism_independent_work_without_mixing_tasks(gs):
    task = _named_task()
    a = task.with_settings({"placement.z": 0.6})
    b = task.with_settings({"placement.z": 0.64, "tool.yaw": 0.3})
    pa, pb = a.path(gs), b.path(gs)
    # the same samples in W, placed differently: each as a task built afresh gives it
    fresh = _named_task()
    fresh_b = fresh.with_settings({"placement.z": 0.64, "tool.yaw": 0.3})
    np.testing.assert_array_equal(pb.X, fresh_b.path(gs).X)
    np.testing.assert_allclose(pa.X[:, 2] + 0.04, pb.X[:, 2], atol=1e-12)  # placement.z moves z
    # a denser copy gets its own path, before and after the coarse one was computed
    dense = b.refined(rate=5)
    assert len(dense.path(gs).X) > 4 * len(pb.X) - 10
    assert len(b.path(gs).X) == len(pb.X)
    # a copy without the path and one with other poses
    X2 = np.array(task.poses) * 0.5
    other = Task(X2, coordinates=task.coordinates, placement={"offset": (0, 0, 0.62)})
    np.testing.assert_allclose(other.platform_poses(gs)[:, :3], X2[:, :3] + [0, 0, 0.62], atol=1e-12)
    # the cached evaluation equals a new one of a new mechanism
    ev1 = task_evaluation(gs, b)
    ev2 = task_evaluation(parasynth.load_mechanism("gough_stewart_6ups"), _named_task().with_settings(
        {"placement.z": 0.64, "tool.yaw": 0.3}))
    np.testing.assert_array_equal(ev1.X, ev2.X)
    np.testing.assert_array_equal(ev1.dynamic_forces, ev2.dynamic_forces)
