"""The push loop's per-step shortcuts give what the direct computations give, bit for bit."""

from __future__ import annotations

import numpy as np

from cart.trajectories import FunctionTrajectory, trajectory_1, trajectory_2
from wholebody.contacts.allocation import TorqueConstraint, _torque_rows
from wholebody.push.controller import horizon_times, path_speed


def test_path_speed_is_the_sampled_velocity_norm():
    for traj in (trajectory_1(), trajectory_2(), trajectory_2(duration=20.0)):
        for t in np.linspace(-1.0, traj.duration + 2.0, 997).tolist():
            v = traj.sample(t)[1]
            assert traj.path_speed(t) == float(np.hypot(v[0], v[1]))
            assert path_speed(traj, t) == traj.path_speed(t)


def test_path_speed_of_a_trajectory_without_one_samples_it():
    traj = FunctionTrajectory(lambda t: (np.zeros(3), np.array([3.0 * t, 4.0 * t, 1.0]), np.zeros(3)), 5.0)
    assert path_speed(traj, 2.0) == 10.0


def test_horizon_times_are_linspace():
    assert horizon_times(1.5, 7) == tuple(float(h) for h in np.linspace(0.0, 1.5, 7))


def _rows_by_joint(n, constraints, margin):
    """The torque rows written out joint by joint: +J_j then -J_j, right-hand sides cap -+ g held at 0."""
    rows, rhs, labels = [], [], []
    for i, c in enumerate(constraints):
        if c is None:
            continue
        names = c.joints or tuple(f"joint {j}" for j in range(len(c.bias)))
        for j in range(len(c.bias)):
            cap = (1.0 - margin) * c.limit[j]
            for sgn in (1.0, -1.0):
                row = np.zeros(6 * n)
                row[6 * i : 6 * i + 6] = sgn * c.jacobian[:, j]
                rows.append(row)
                rhs.append(max(cap - sgn * c.bias[j], 0.0))
                labels.append(f"arm{i} {names[j]} torque limit ({c.limit[j]:g} N m)")
    return np.array(rows).reshape(-1, 6 * n), np.array(rhs), labels


def test_torque_rows_match_the_rows_written_joint_by_joint():
    rng = np.random.default_rng(3)
    for _ in range(50):
        constraints = []
        for _ in range(int(rng.integers(1, 4))):
            nj = int(rng.integers(1, 8))
            named = tuple(f"j{k}" for k in range(nj)) if rng.random() < 0.5 else ()
            c = TorqueConstraint(rng.normal(size=(6, nj)), 30.0 * rng.normal(size=nj), rng.uniform(5, 60, nj), named)
            constraints.append(None if rng.random() < 0.2 else c)
        margin = float(rng.uniform(0.0, 0.5))
        rows, rhs, labels, over = _torque_rows(len(constraints), constraints, margin)
        want = _rows_by_joint(len(constraints), constraints, margin)
        assert np.array_equal(rows, want[0]) and np.array_equal(rhs, want[1]) and labels == want[2]
        expected_over = [
            f"arm{i} {(c.joints or tuple(f'joint {j}' for j in range(len(c.bias))))[j]}"
            for i, c in enumerate(constraints)
            if c is not None
            for j in range(len(c.bias))
            if abs(c.bias[j]) > (1.0 - margin) * c.limit[j]
        ]
        assert over == expected_over
