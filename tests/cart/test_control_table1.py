"""LQR gain (Hamiltonian eigenvector CARE vs scipy), the fl_lqr/kanayama controllers, Table I data."""

import math

import numpy as np
import pytest
import scipy.linalg

from cart import control, model
from cart import table1
from cart.params import CartParams


def _error_system(rng):
    p = CartParams(
        rng.uniform(8, 40), rng.uniform(-0.3, 0.5), rng.uniform(-0.2, 0.2), rng.uniform(0.5, 4.0), rng.uniform(0, 8)
    )
    q = np.r_[rng.normal(size=2), rng.uniform(-math.pi, math.pi)]
    qd = rng.normal(size=3)
    return model.mass_matrix(q, p), model.coriolis_matrix(q, qd, p)


def test_hamiltonian_care_matches_scipy_and_solves_the_riccati_equation():
    rng = np.random.default_rng(7)
    eye = np.eye(3)
    qw = np.diag([400.0] * 3 + [20.0] * 3)
    rw = 0.01 * eye
    for _ in range(20):
        mm, cc = _error_system(rng)
        minv = np.linalg.inv(mm)
        a = np.block([[-2.0 * eye, eye], [np.zeros((3, 3)), -minv @ cc]])
        b = np.vstack([np.zeros((3, 3)), minv])
        x = control.care_hamiltonian(a, b, qw, rw)
        ref = scipy.linalg.solve_continuous_are(a, b, qw, rw)
        np.testing.assert_allclose(x, ref, rtol=1e-8, atol=1e-8 * np.abs(ref).max())
        residual = a.T @ x + x @ a - x @ b @ np.linalg.solve(rw, b.T) @ x + qw
        assert np.abs(residual).max() < 1e-7 * np.abs(qw).max()
        k = control.lqr_gain(mm, cc, 2.0 * eye, qw, rw)
        assert np.linalg.eigvals(a - b @ k).real.max() < 0  # closed loop stable


def test_care_falls_back_to_scipy_when_the_hamiltonian_has_imaginary_axis_eigenvalues():
    # uncontrollable, undamped mode: no stabilising solution -> scipy's own error
    a = np.array([[0.0, 1.0], [-1.0, 0.0]])
    b = np.zeros((2, 1))
    with pytest.raises((np.linalg.LinAlgError, ValueError)):
        control.care_hamiltonian(a, b, np.eye(2), np.eye(1))


def test_handle_matches_the_shipped_cart():
    # robots/shopping_cart.py CART_HANDLE_X (cart may not import robots: compared here in the test)
    from robots import shopping_cart

    assert table1.HANDLE_X == pytest.approx(shopping_cart.CART_HANDLE_X)


def test_trajectory_sample_is_numpy_interp_of_the_grid_and_poses_agree():
    from cart.trajectories import trajectory_1, trajectory_2

    rng = np.random.default_rng(3)
    for traj in (trajectory_1(12.0), trajectory_2(30.0)):
        tg, xg, yg = traj._grid()[:3]
        ts = np.concatenate([np.arange(0, 1201) * 0.01, rng.uniform(-1.0, 31.0, 300), [0.0, tg[-1], 40.0]])
        for t in ts:
            q, _, _ = traj.sample(t)
            assert q[0] == np.interp(t, tg, xg) and q[1] == np.interp(t, tg, yg)  # bit for bit
        poses = traj.poses(ts)
        np.testing.assert_array_equal(poses, np.array([traj.sample(t)[0] for t in ts]))


def test_table1_runs_do_not_depend_on_the_worker_processes():
    tests = (table1.TESTS[0], table1.TESTS[10])
    one = table1.run_table1(tests, duration=6.0, workers=1)
    seen = []
    two = table1.run_table1(tests, duration=6.0, workers=2, progress=seen.append)
    assert sorted(seen) == [1, 11]
    for a, b in zip(one, two):
        assert a.as_json() == b.as_json()
        np.testing.assert_array_equal(a.run.q, b.run.q)
        np.testing.assert_array_equal(a.run_no_estimation.params_hat, b.run_no_estimation.params_hat)
    # the same as evaluating each test on its own
    alone = table1.evaluate(table1.TESTS[10], duration=6.0).as_json()
    assert {k: v for k, v in one[1].as_json().items() if k != "online"} == alone


def test_sensor_loop_of_the_excitation_study_is_table1s_loop():
    from studies.excitation_study import _SensorLoop

    assert issubclass(_SensorLoop, table1.EstimatingLoop)


def test_table1_test11_online_estimator_finds_the_load_changes():
    """Test 11 loads 10 kg at 10 s and removes 5 at 20 s: the online estimator reports both, with the new masses."""
    run = table1.run_test(table1.TESTS[10], estimator="online")
    changes = run.events
    assert len(changes) == 2
    for c, (t_true, m_true) in zip(changes, table1.TESTS[10].mass_changes):
        assert t_true - 1.0 <= c["t_change"] <= t_true + 5.0  # found once the motion shows it (a turn)
        assert abs(c["mass_after"] - m_true) < 0.1 * m_true
    with pytest.raises(table1.ParameterError):
        table1.run_test(table1.TESTS[0], estimator="kalman")


def test_table1_test_9_closes_with_the_online_estimator_at_seed_0():
    """`cartpush reproduce`'s default seed: the online row of test 9 (5 cm pose noise) ran off to 0.8 kg and the
    loop diverged (NaN pose) when the regression held a direction that was not the established one."""
    from cart.table1 import TESTS, run_test

    test = next(t for t in TESTS if t.test == 9)
    run = run_test(test, estimator="online", seed=0)
    assert np.all(np.isfinite(run.q))
    assert abs(run.params_hat[-1, 0] - 20.0) < 3.0
