"""Excitation: regressor vs the cart model, noise propagation, CRLB, planner vs brute force, closed-loop EKF."""

import itertools

import numpy as np
import pytest

from cart.ekf import input_noise_covariance
from cart.model import (
    contact_wrench_to_generalized,
    coriolis_matrix,
    damping_force,
    forward_dynamics,
    generalized_to_body,
    mass_matrix,
)
from cart.params import CartParams
from cart.trajectories import trajectory_2
from wholebody.contacts.allocation import ArmLimits
from wholebody.contacts.handle import HandleSegment, grasp_map
from studies.excitation_study import com_convergence_traj2
from wholebody.contacts.excitation import (
    OBJECTIVES,
    WrenchNoise,
    _segment_tables,
    cart_wrench_covariance,
    com_covariance,
    com_crlb_course,
    default_prior,
    fisher_information,
    input_model,
    measurement_covariance,
    objective_value,
    plan_contact_schedule,
    reduced_regressor,
    sample_push,
    schedule_points,
    schedule_score,
)

GUESS = CartParams(16.0, 0.3, 0.0, 1.6, 4.0)


def test_reduced_regressor_matches_cart_model():
    rng = np.random.default_rng(0)
    for _ in range(10):
        p = CartParams(rng.uniform(10, 40), rng.uniform(-0.2, 0.5), rng.uniform(-0.2, 0.2), rng.uniform(0.5, 3), 3.0)
        th, v, om, vd, od = rng.normal(size=5)
        c, s = np.cos(th), np.sin(th)
        q = np.array([0.1, 0.2, th])
        qd = np.array([v * c, v * s, om])
        qdd = np.array([vd * c - v * om * s, vd * s + v * om * c, od])  # unicycle: no lateral slip
        gamma = mass_matrix(q, p) @ qdd + coriolis_matrix(q, qd, p) @ qd + damping_force(qd, p.sigma)
        body = generalized_to_body(q, gamma)
        pred = reduced_regressor(v, vd, om, od) @ p.phi + p.sigma * np.array([v, om])
        assert np.allclose(pred, body[[0, 2]], atol=1e-10)


def test_measurement_covariance_matches_monte_carlo():
    rng = np.random.default_rng(1)
    noise = WrenchNoise(3.0, 0.3)
    p = HandleSegment.default().point(0.45)
    n = rng.normal(size=(200_000, 6)) * np.array([3.0, 3.0, 0, 0, 0, 0.3])
    samples = (grasp_map(p) @ n.T)[[0, 2]]
    assert np.allclose(np.cov(samples), measurement_covariance(p, noise), rtol=0.02, atol=0.01)


def test_cart_wrench_covariance_matches_cart_model_map():
    # independent map: cart.model.contact_wrench_to_generalized (eq. 23-24 in the plane, rotated to {s})
    rng = np.random.default_rng(2)
    noise = WrenchNoise(2.0, 0.4)
    p = HandleSegment.default().point(0.1)
    q = np.array([0.3, -0.2, 0.7])
    n = rng.normal(size=(60_000, 3)) * np.array([2.0, 2.0, 0.4])
    g = np.array([contact_wrench_to_generalized(q, p, f[:2], f[2]) for f in n])
    cov = cart_wrench_covariance(p, noise.covariance_ee(), theta=q[2])
    w = np.linalg.inv(np.linalg.cholesky(cov))  # whitened: identity within the Monte Carlo error (~0.6 %)
    assert np.allclose(w @ np.cov(g.T) @ w.T, np.eye(3), atol=0.03)


def test_gamma_cov_density_convention_matches_held_wrench_noise():
    # the loop passes gamma_cov = (per-sample covariance) * dt: the velocity increment over dt of a
    # wrench noise held over dt must then have the covariance the EKF adds (A from finite differences
    # of cart.model.forward_dynamics, not from cart.ekf)
    p = CartParams(20.0, 0.3, 0.15, 2.27, 4.0)
    q, qd = np.array([0.0, 0.0, 0.4]), np.array([0.5 * np.cos(0.4), 0.5 * np.sin(0.4), 0.3])
    gamma = np.array([5.0, 1.0, 2.0])
    A = np.column_stack(
        [
            (forward_dynamics(q, qd, gamma + 1e-4 * e, p) - forward_dynamics(q, qd, gamma - 1e-4 * e, p)) / 2e-4
            for e in np.eye(3)
        ]
    )
    sigma = cart_wrench_covariance(HandleSegment.default().point(0.0), WrenchNoise().covariance_ee(), q[2])
    dt = 0.01
    x = np.concatenate([q, qd, p.phi])
    assert np.allclose(input_noise_covariance(x, sigma * dt, dt), A @ sigma @ A.T * dt**2, rtol=1e-6, atol=1e-14)


def test_input_model_fused_error_is_orthogonal_and_measured_is_not():
    rng = np.random.default_rng(3)
    sensor, act = WrenchNoise(3.0, 0.3), WrenchNoise(2.0, 0.5)
    e = rng.normal(size=(400_000, 2)) * [2.0, 0.5]
    n = rng.normal(size=(400_000, 2)) * [3.0, 0.3]
    command = rng.normal(size=(400_000, 2)) * [10.0, 1.0]
    applied, reading = command + e, command + e + n
    fused = input_model("fused", sensor, act)
    gains = np.array([fused.gain_force, fused.gain_torque])
    for mode, inp in [("fused", command + gains * (reading - command)), ("measured", reading)]:
        err = applied - inp
        std = input_model(mode, sensor, act).noise
        assert np.allclose(err.std(axis=0), [std.force, std.torque], rtol=0.01)
        corr = [np.corrcoef(err[:, i], inp[:, i])[0, 1] for i in range(2)]
        if mode == "fused":
            assert np.allclose(corr, 0.0, atol=0.01)  # conditional mean: error uncorrelated with the input
        else:
            assert all(c < -0.1 for c in corr)  # errors in variables
    # the fused gain is the least-squares regression of the applied wrench on the reading given the command
    beta = [np.polyfit(reading[:, i] - command[:, i], applied[:, i] - command[:, i], 1)[0] for i in range(2)]
    assert np.allclose(beta, gains, atol=0.01)
    with pytest.raises(Exception, match="unknown EKF input"):
        input_model("raw")


def test_fisher_information_is_sum_of_whitened_regressors():
    s = sample_push(trajectory_2(), dt=0.5)
    h = HandleSegment.default()
    pts = np.array([h.point(0.1 + 0.3 * (k % 2)) for k in range(len(s.t))])
    info = fisher_information(s, pts)
    ref = np.zeros((4, 4))
    for k in range(len(s.t)):
        Y = reduced_regressor(s.v[k], s.vdot[k], s.omega[k], s.omegadot[k])
        L = np.linalg.cholesky(np.linalg.inv(measurement_covariance(pts[k])))
        ref += (L.T @ Y).T @ (L.T @ Y)
    assert np.allclose(info, ref)
    assert np.allclose(fisher_information(s, pts, sensor_dt=0.01), 50.0 * ref)
    # a straight push (Traj. 1 speed profile, no turn) cannot excite m dx: the score is ~0
    straight = sample_push(trajectory_2(turns=()), dt=0.5)
    phi = CartParams(16, 0.3, 0.0, 1.6).phi
    assert schedule_score(straight, lambda t: 0.25, phi) < 1e-9 * schedule_score(s, lambda t: 0.25, phi)


def test_handle_ends_dominate_interior_contacts():
    # R(p)^-1 is quadratic in the lateral offset with a PSD curvature: time-sharing the two ends with the
    # same mean offset gives at least the information of any interior point (Loewner order)
    h = HandleSegment.default()
    lo, hi = (np.linalg.inv(measurement_covariance(h.point(s))) for s in (0.0, h.length))
    for s in np.linspace(0.0, h.length, 11):
        lam = s / h.length
        gap = lam * hi + (1.0 - lam) * lo - np.linalg.inv(measurement_covariance(h.point(s)))
        assert np.linalg.eigvalsh(gap)[0] > -1e-9


def test_com_covariance_matches_monte_carlo_of_bayesian_regression():
    rng = np.random.default_rng(4)
    truth = CartParams(20.0, 0.3, 0.15, 2.27, 0.0)
    s = sample_push(trajectory_2(), dt=0.1)
    h = HandleSegment.default()
    pts = np.array([h.point(0.5 if t < 15 else 0.0) for t in s.t])
    noise = WrenchNoise(3.0, 0.3)
    Y = reduced_regressor(s.v, s.vdot, s.omega, s.omegadot)
    R = np.array([measurement_covariance(p, noise) for p in pts])
    L = np.linalg.cholesky(R)
    Rinv = np.linalg.inv(R)
    P0 = np.diag([4.0, 1.0, 1.0, 1.0])
    info = fisher_information(s, pts, noise)
    A = info + np.linalg.inv(P0)
    coms = []
    for _ in range(2000):
        phi0 = truth.phi + np.linalg.cholesky(P0) @ rng.normal(size=4)  # prior draw (Bayesian bound)
        y = Y @ truth.phi + np.einsum("nij,nj->ni", L, rng.normal(size=(len(s.t), 2)))
        post = np.linalg.solve(A, np.linalg.solve(P0, phi0) + np.einsum("nji,njk,nk->i", Y, Rinv, y))
        coms.append(post[1:3] / post[0])
    emp = np.cov(np.array(coms).T)
    assert np.allclose(emp, com_covariance(info, truth.phi, P0), rtol=0.15, atol=1e-7)


@pytest.mark.parametrize("objective", OBJECTIVES)
def test_planner_matches_brute_force(objective):
    s = sample_push(trajectory_2(), dt=0.25)
    kw = dict(n_segments=3, n_candidates=5, objective=objective, sensor_dt=0.01)
    plan = plan_contact_schedule(s, GUESS.phi, sigma=4.0, exhaustive_limit=0, **kw)  # coordinate ascent
    assert plan.effort <= plan.budget
    assert plan.score >= plan.fixed_score
    assert plan.score == pytest.approx(
        schedule_score(s, plan.schedule, GUESS.phi, objective=objective, sensor_dt=0.01), rel=1e-9
    )
    cand = np.linspace(0, 0.5, 5)
    _, info, effort = _segment_tables(
        s, GUESS.phi, 4.0, HandleSegment.default(), cand, 3, WrenchNoise(), ArmLimits(), sensor_dt=0.01
    )
    best = -np.inf
    for idx in itertools.product(range(5), repeat=3):
        if sum(effort[k, j] for k, j in enumerate(idx)) <= plan.budget:
            best = max(best, objective_value(np.array([info[k, j] for k, j in enumerate(idx)]), GUESS.phi, objective))
    assert plan.score == pytest.approx(best, rel=1e-9)
    assert plan_contact_schedule(s, GUESS.phi, sigma=4.0, **kw).score == pytest.approx(best, rel=1e-9)  # exhaustive


def test_planned_schedule_lowers_the_com_bound_of_traj2_at_all_times():
    # planned on the EKF's initial guess (CoM (0.3, 0)), judged on the true cart (CoM (0.3, 0.15)): the
    # path objective with 2-s segments gives a lower CoM bound than every fixed contact at 10, 20 and 30 s
    s = sample_push(trajectory_2(), dt=0.1)
    truth = CartParams(20.0, 0.3, 0.15, 20.0 * 1.36 / 12.0, 4.0)
    noise = input_model("fused").noise
    P0 = default_prior(GUESS.phi)
    plan = plan_contact_schedule(
        s, GUESS.phi, 4.0, n_segments=15, n_candidates=3, noise=noise, objective="com_a_path", sensor_dt=0.01
    )
    times = (10.0, 20.0, 30.0)
    bound = lambda sched: np.sqrt(
        np.trace(
            com_crlb_course(s, sched, truth.phi, times, noise, P0, 0.01),  # noqa: E731
            axis1=1,
            axis2=2,
        )
    )
    planned = bound(plan.schedule)
    for c in np.linspace(0.0, 0.5, 5):
        assert np.all(planned < 0.9 * bound(lambda t, c=c: c))
    # the course ends at the bound of the whole push
    info = fisher_information(s, schedule_points(s, plan.schedule), noise, sensor_dt=0.01)
    assert np.allclose(
        com_crlb_course(s, plan.schedule, truth.phi, [30.0], noise, P0, 0.01)[0], com_covariance(info, truth.phi, P0)
    )


def test_closed_loop_ekf_is_consistent_with_fused_input_and_biased_with_measured():
    # 12 s of Traj. 2 (acceleration and the first turn), 2 seeds: the EKF fed the fused wrench with its
    # contact-dependent covariance has mean NIS ~6 and an unbiased mass; fed the raw F/T reading its mass
    # is biased upward (errors in variables: the reading's noise is also in the regressor)
    for seed in (0, 1):
        fused = com_convergence_traj2(lambda t: 0.5, seed=seed, duration=12.0)
        assert 5.6 < fused.mean_nis < 6.4
        assert abs(fused.mass_error[-1]) < 0.6
        assert fused.final_com_error < 3.0 * float(np.hypot(*fused.com_std[-1])) + 0.005
        measured = com_convergence_traj2(
            lambda t: 0.5, seed=seed, duration=12.0, ekf_input="measured", actuation=WrenchNoise(0.0, 0.0)
        )
        assert measured.mass_error[-1] > 1.0
