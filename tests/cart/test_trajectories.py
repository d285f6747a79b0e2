"""Trajectories as objects: waypoint paths and functions of time, checked against finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cart.trajectories import FunctionTrajectory, WaypointTrajectory, paper_trajectory


def test_waypoint_path_passes_through_its_waypoints_and_stops_at_the_last():
    wps = ((0.0, 0.0), (2.0, 0.0), (4.0, 1.5), (6.0, 1.5))
    traj = WaypointTrajectory(wps, speed=0.6, accel=0.4)
    q0, qd0, _ = traj.sample(0.0)
    qe, qde, _ = traj.sample(traj.duration + 1.0)
    np.testing.assert_allclose(q0[:2], wps[0], atol=1e-9)
    np.testing.assert_allclose(qe[:2], wps[-1], atol=1e-3)
    assert np.allclose(qd0, 0.0) and np.allclose(qde, 0.0)
    # the path's length is at least the chord of the waypoints
    assert traj.length >= sum(math.dist(a, b) for a, b in zip(wps, wps[1:])) - 1e-9


def test_waypoint_velocity_is_the_derivative_of_the_pose_and_has_no_lateral_slip():
    traj = WaypointTrajectory(((0.0, 0.0), (2.0, 1.0), (4.0, -1.0), (5.0, 0.0)), speed=0.5)
    h = 1e-4
    for t in np.linspace(0.5, traj.duration - 0.5, 25):
        q, qd, qdd = traj.sample(t)
        qp, qdp, _ = traj.sample(t + h)
        qm, qdm, _ = traj.sample(t - h)
        dq = (qp - qm) / (2 * h)
        dq[2] = ((qp[2] - qm[2] + math.pi) % (2 * math.pi) - math.pi) / (2 * h)
        np.testing.assert_allclose(qd, dq, atol=2e-3)
        # nonholonomic: the velocity is along the heading (paper eq. 1-3)
        assert abs(-math.sin(q[2]) * qd[0] + math.cos(q[2]) * qd[1]) < 1e-9
        np.testing.assert_allclose(qdd[:2], (qdp[:2] - qdm[:2]) / (2 * h), atol=5e-2)


def test_bad_waypoints_are_refused():
    with pytest.raises(ValueError, match="waypoints"):
        WaypointTrajectory(((0.0, 0.0),))
    with pytest.raises(ValueError, match="differ"):
        WaypointTrajectory(((0.0, 0.0), (0.0, 0.0)))


def test_function_trajectory_checks_shapes():
    traj = FunctionTrajectory(lambda t: (np.array([t, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.zeros(3)), 5.0)
    assert traj.sample(2.0)[0][0] == 2.0
    with pytest.raises(ValueError, match="shape"):
        FunctionTrajectory(lambda t: (np.zeros(2), np.zeros(3), np.zeros(3)), 1.0).sample(0.0)


def test_paper_trajectories_by_number():
    assert paper_trajectory(2).turns and not paper_trajectory(1).turns
    with pytest.raises(ValueError):
        paper_trajectory(3)
