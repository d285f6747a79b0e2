"""Tests of wholebody.motion.timing: toppra limits, optimality vs uniform scaling, EE path through the IK."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.interpolate import CubicSpline

import robots
from wholebody.errors import TrajectoryInfeasibleError, WholeBodyError
from wholebody.motion.experiments import initial_state
from wholebody.motion.kinematics import wholebody_for
from wholebody.motion.timing import ee_path_time_optimal, time_optimal

V = np.full(9, 0.9)
A = np.full(9, 2.0)


def _uniform_duration(wp, v, a):
    """Shortest T for s = smoothstep(t / T) along the same chord-length spline (independent code)."""
    seg = np.linalg.norm(np.diff(wp, axis=0), axis=1)
    s = np.r_[0, np.cumsum(seg)] / seg.sum()
    spl = CubicSpline(s, wp)
    tau = np.linspace(0, 1, 20001)
    sv, s1, s2 = tau**2 * (3 - 2 * tau), 6 * tau * (1 - tau), 6 - 12 * tau
    vel = np.abs(spl(sv, 1) * s1[:, None]) / v
    acc = np.abs(spl(sv, 2) * s1[:, None] ** 2 + spl(sv, 1) * s2[:, None]) / a
    return max(vel.max(), np.sqrt(acc.max())), spl


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_time_optimal_respects_limits_and_beats_uniform_scaling(seed):
    rng = np.random.default_rng(seed)
    wp = np.cumsum(rng.normal(size=(rng.integers(3, 8), 9)) * 0.3, axis=0)
    tr = time_optimal(wp, V, A, sample_dt=0.002)
    assert np.all(np.abs(tr.qd) <= V * (1 + 1e-9))
    assert np.all(np.abs(tr.qdd) <= A * (1 + 1e-9))
    np.testing.assert_allclose(tr.q[0], wp[0], atol=1e-9)
    np.testing.assert_allclose(tr.q[-1], wp[-1], atol=1e-9)
    np.testing.assert_allclose(tr.qd[[0, -1]], 0.0, atol=1e-9)
    T_uniform, spl = _uniform_duration(wp, V, A)
    assert tr.duration <= T_uniform
    # the trajectory stays on the geometric path: every sample is the spline at some s
    s_fine = np.linspace(0, 1, 20001)
    pts = spl(s_fine)
    d = np.min(np.linalg.norm(tr.q[::25, None, :] - pts[None, :, :], axis=2), axis=1)
    assert d.max() < 1e-3


def test_infeasible_raises():
    wp = np.array([[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(WholeBodyError):
        time_optimal(wp, [0.0, 1.0], [1.0, 1.0])
    with pytest.raises(WholeBodyError):
        time_optimal(np.array([[0.0, 0.0], [0.0, 0.0]]), [1.0, 1.0], [1.0, 1.0])


def test_toppra_none_becomes_trajectory_infeasible_error(monkeypatch):
    import toppra.algorithm

    monkeypatch.setattr(toppra.algorithm.TOPPRA, "compute_trajectory", lambda self, a, b: None)
    with pytest.raises(TrajectoryInfeasibleError):
        time_optimal(np.array([[0.0, 0.0], [1.0, 1.0]]), [1.0, 1.0], [1.0, 1.0])


def test_ee_path_through_ik_then_toppra():
    wb = wholebody_for(robots.load("wmra"))
    x0 = initial_state(wb)
    T0 = wb.ee_placement(x0)
    targets = [pin.SE3(T0.rotation, T0.translation + [0.05 * k, 0.02 * np.sin(k), 0.0]) for k in range(1, 11)]
    res = ee_path_time_optimal(wb, x0, targets, acc_limits=np.full(9, 2.0))
    assert res.max_ik_error_m < 1e-4
    vmax = np.r_[wb.arm_velocity_limit, wb.wheel_velocity_limit]
    assert np.all(np.abs(res.trajectory.qd) <= vmax * (1 + 1e-9))
    assert np.all(np.abs(res.trajectory.qdd) <= 2.0 * (1 + 1e-9))
    # the waypoints' arm angles reproduce the EE targets with their base poses
    for x, T in zip(res.states, targets):
        assert np.linalg.norm(wb.ee_placement(x).translation - T.translation) < 1e-4
    np.testing.assert_allclose(res.trajectory.q[-1], res.joint_path[-1], atol=1e-9)
