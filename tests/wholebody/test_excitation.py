"""Excitation score: regressor vs the cart model, noise propagation, planner vs brute force."""
import itertools

import numpy as np
import pytest

from cart.model import coriolis_matrix, damping_force, generalized_to_body, mass_matrix
from cart.params import CartParams
from cart.trajectories import trajectory_2
from wholebody.contact import HandleSegment, grasp_map
from wholebody.excitation import (
    WrenchNoise,
    excitation_score,
    fisher_information,
    measurement_covariance,
    plan_contact_schedule,
    reduced_regressor,
    sample_push,
    schedule_score,
)


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
    # a straight push (Traj. 1 speed profile, no turn) cannot excite m dx: the score is ~0
    straight = sample_push(trajectory_2(turns=()), dt=0.5)
    phi = CartParams(16, 0.3, 0.0, 1.6).phi
    assert schedule_score(straight, lambda t: 0.25, phi) < 1e-9 * schedule_score(s, lambda t: 0.25, phi)


def test_planner_beats_fixed_contact_and_matches_brute_force():
    s = sample_push(trajectory_2(), dt=0.25)
    guess = CartParams(16.0, 0.3, 0.0, 1.6, 4.0)
    plan = plan_contact_schedule(s, guess.phi, sigma=4.0, n_segments=3, n_candidates=5)
    assert plan.effort <= plan.budget
    assert plan.score >= plan.fixed_score
    assert plan.score == pytest.approx(schedule_score(s, plan.schedule, guess.phi), rel=1e-9)
    # brute force over all 5^3 schedules within the same budget
    from wholebody.excitation import _segment_tables

    cand = np.linspace(0, 0.5, 5)
    from wholebody.allocation import ArmLimits

    _, info, effort = _segment_tables(s, guess.phi, 4.0, HandleSegment.default(), cand, 3, WrenchNoise(), ArmLimits())
    best = -np.inf
    for idx in itertools.product(range(5), repeat=3):
        if sum(effort[k, j] for k, j in enumerate(idx)) <= plan.budget:
            best = max(best, excitation_score(sum(info[k, j] for k, j in enumerate(idx)), guess.phi))
    assert plan.score == pytest.approx(best, rel=1e-9)
