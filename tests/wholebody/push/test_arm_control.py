"""The torque arm law's budget, its force loop's reference and its wrench estimate (`wholebody.push.arm_control.TorqueArmLaw`).

No physics here: a law on a random 6 x 7 Jacobian and inertia, fed states and readings directly.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from wholebody.push.arm_control import (
    TorqueArmGains,
    TorqueArmLaw,
    fit_in_limits,
    fused_estimator,
    torque_budget,
)

LIMIT = np.array([320.0, 320.0, 176.0, 176.0, 110.0, 40.0, 40.0])  # the iiwa's effort limits (N m)


def _arm() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(11)
    A = rng.normal(size=(7, 7))
    return 0.5 * rng.normal(size=(6, 7)), A @ A.T + 7.0 * np.eye(7)


def _law(gains: TorqueArmGains, w: np.ndarray, limit: np.ndarray = LIMIT) -> tuple[TorqueArmLaw, np.ndarray]:
    J, M = _arm()
    law = TorqueArmLaw(limit, gains, 0.002)
    z = np.zeros(7)
    law.begin(w, z, z, z, J, M, t_end=0.01, dt=0.01)
    return law, J


def test_budget_keeps_the_task_part_and_fits_the_hands_feedback_into_the_limits():
    w = np.array([20.0, -5.0, -40.0, 0.0, 0.0, 2.0])
    gains = TorqueArmGains(
        feedforward="bias", force_integral=0.0, fusion_tau=0.0, stiffness=0.0, damping=0.0, budget=True
    )
    law, J = _law(gains, w)
    free, _ = _law(gains, w, limit=np.full(7, 1e9))  # the same law without limits
    bias = 0.6 * LIMIT * np.array([1.0, -1.0, 0.5, 0.5, 0.0, 0.0, 0.0])  # the arm's weight: most of two joints
    reading = w + np.array([0.0, 0.0, 60.0, 0.0, 0.0, 0.0])  # the hand presses 60 N less than allocated
    z = np.zeros(7)
    asked = free.torque(0.0, z, z, bias, wrench_measured=reading)
    task = J.T @ w + bias
    assert np.any(np.abs(asked) > LIMIT) and np.all(np.abs(task) < LIMIT)
    tau = law.torque(0.0, z, z, bias, wrench_measured=reading)
    assert np.all(np.abs(tau) <= LIMIT + 1e-9)
    assert law.peak_ratio <= 1.0 + 1e-9 and law.saturated_steps == 0 and law.scaled_steps == 1
    # the task part whole; the feedback a hand wrench (J^T u'), none of it in the hand's null space
    u_asked = np.linalg.lstsq(J.T, asked - task, rcond=None)[0]
    u_fit, res, *_ = np.linalg.lstsq(J.T, tau - task, rcond=None)
    np.testing.assert_allclose(J.T @ u_fit, tau - task, atol=1e-6)
    # closer to the asked feedback than the uniform scale that fits (the joints with room keep giving)
    s = torque_budget(task, asked - task, LIMIT)
    assert 0.0 < s < 1.0
    dist = lambda x: np.linalg.norm((J.T @ (x - u_asked)) / LIMIT)  # noqa: E731
    assert dist(u_fit) < dist(s * u_asked) - 1e-3
    np.testing.assert_allclose(law.peak_task_ratio, np.max(np.abs(task) / LIMIT))
    np.testing.assert_allclose(law.peak_joint_ratio, np.abs(tau) / LIMIT)
    clipped, _ = _law(replace(gains, budget=False), w)  # the sum clipped per joint, each joint's full effort
    np.testing.assert_allclose(
        clipped.torque(0.0, z, z, bias, wrench_measured=reading), np.clip(asked, -LIMIT, LIMIT), atol=1e-9
    )
    assert clipped.peak_ratio > 1.0 and clipped.saturated_steps == 1


def test_fit_in_limits_is_the_closest_that_fits():
    from scipy.optimize import minimize

    J, _ = _arm()
    A = J.T
    base = 0.5 * LIMIT * np.array([1.0, -1.0, 0.3, 0.0, 0.2, -0.5, 0.0])
    x = np.array([300.0, -100.0, 200.0, 30.0, -20.0, 10.0])  # far beyond the limits
    fit = fit_in_limits(A, x, base, LIMIT)
    assert fit is not None and np.all(np.abs(base + A @ fit) <= LIMIT * (1.0 + 1e-9))
    cost = lambda y: float(np.sum(((A @ (y - x)) / LIMIT) ** 2))  # noqa: E731
    cons = [{"type": "ineq", "fun": lambda y: LIMIT - np.abs(base + A @ y)}]
    ref = minimize(cost, np.zeros(6), constraints=cons, method="SLSQP", options={"ftol": 1e-12, "maxiter": 500})
    assert cost(fit) <= cost(ref.x) * (1.0 + 1e-6) + 1e-12
    assert fit_in_limits(A, 1e-3 * x, base, LIMIT) is not None
    small = 1e-3 * x
    assert fit_in_limits(A, small, base, LIMIT) is small  # it fits: kept as it is
    assert fit_in_limits(A, x, 1.1 * LIMIT, LIMIT) is None  # the base alone exceeds: nothing fits


def test_fused_estimate_stays_bounded_where_the_joints_do_not_see_the_hand():
    """At a straight elbow a push along the arm loads no joint: the joint side alone divides the joint torques'
    noise by a vanishing singular value; the fused estimate takes the F/T's reading along that direction."""
    J, M = _arm()
    U, S, Vt = np.linalg.svd(J)
    S[-1] = 1e-3  # one wrench direction the joints hardly see (mostly a force)
    Js = U @ np.diag(S) @ Vt[:6]
    blind = U[:, -1]
    truth = np.array([30.0, -5.0, -20.0, 0.0, 0.0, 1.0])
    rng = np.random.default_rng(9)
    noise = 1e-3 * LIMIT * rng.normal(size=7)  # the joint torque sensors' white noise
    ft = truth + np.r_[rng.normal(0.0, 3.0, 3), 0.0, 0.0, 0.0]
    errors = {}
    for ft_noise in (None, (3.0, math.inf)):
        # the sensors' raw reading (no motor-side low-pass): the fit weighs their full white noise
        gains = TorqueArmGains(feedforward="bias", fusion_tau=0.0, ft_noise=ft_noise, motor_torque_tau=0.0)
        law = TorqueArmLaw(LIMIT, gains, 0.002)
        z = np.zeros(7)
        law.begin(truth, z, z, z, Js, M, t_end=0.01, dt=0.01)
        law.joint_torque_sample(-Js.T @ truth + noise)
        errors[ft_noise is None] = float(np.linalg.norm(law.joint_estimate(ft) - truth))
    assert errors[True] > 100.0  # the joint side alone: the joints' noise over 1e-3
    assert errors[False] < 10.0  # the F/T's noise along the blind direction, the joints' elsewhere
    E, F = fused_estimator(Js, 1e-3 * LIMIT, np.r_[3.0, 3.0, 3.0, np.inf, np.inf, np.inf])
    np.testing.assert_allclose(E @ (Js.T @ truth) + F @ truth, truth, atol=1e-6)  # exact without noise
    assert blind @ F @ blind > 0.95 * np.linalg.norm(blind[:3]) ** 2  # the F/T's forces carry it


def test_posture_takes_the_room_the_hands_terms_leave_each_joint():
    w = np.array([20.0, -5.0, -40.0, 0.0, 0.0, 2.0])
    gains = TorqueArmGains(feedforward="bias", null_space=False, budget=True, implicit_damping=False)
    law, J = _law(gains, w)
    q = np.full(7, 0.4)  # 0.4 rad from the plan: the joint impedance asks 80 N m on every joint
    z = np.zeros(7)
    tau = law.torque(0.0, q, z, z)
    task = J.T @ w
    posture = -200.0 * q
    np.testing.assert_allclose(tau, np.clip(task + posture, -LIMIT, LIMIT))
    assert np.any(np.abs(task + posture) > LIMIT) and law.peak_ratio <= 1.0 + 1e-9 and law.saturated_steps == 0


def test_budget_is_zero_when_the_task_part_alone_exceeds_a_limit():
    limit = np.array([10.0, 10.0])
    assert torque_budget(np.array([11.0, 0.0]), np.array([-5.0, 1.0]), limit) == 0.0
    assert torque_budget(np.array([5.0, 0.0]), np.array([10.0, 0.0]), limit) == pytest.approx(0.5)
    assert torque_budget(np.array([5.0, 0.0]), np.array([-30.0, 1.0]), limit) == pytest.approx(0.5)
    assert torque_budget(np.array([5.0, 0.0]), np.array([1.0, 1.0]), limit) == 1.0


def test_a_task_part_beyond_a_limit_is_the_closest_wrench_that_fits():
    w = np.array([0.0, 0.0, -50.0, 0.0, 0.0, 0.0])
    limit = np.full(7, 1.0)
    law, J = _law(TorqueArmGains(feedforward="bias", force_feedback=0.0, budget=True), w, limit=limit)
    z = np.zeros(7)
    tau = law.torque(0.0, z, z, z)
    assert np.all(np.abs(tau) <= 1.0 + 1e-9) and np.any(np.abs(tau) > 0.999)
    w_fit = np.linalg.lstsq(J.T, tau, rcond=None)[0]
    np.testing.assert_allclose(J.T @ w_fit, tau, atol=1e-6)  # still a hand wrench: no clip bent it
    assert w_fit[2] < 0.0  # and it still presses
    assert law.saturated_steps == 0 and law.scaled_steps == 1 and law.peak_task_ratio > 1.0
    # only the bias forces beyond a limit leave nothing to fit: then clipped
    law2, _ = _law(TorqueArmGains(feedforward="bias", force_feedback=0.0, budget=True), w, limit=limit)
    np.testing.assert_allclose(law2.torque(0.0, z, z, np.full(7, 3.0)), np.clip(J.T @ w + 3.0, -1.0, 1.0))


@pytest.mark.parametrize("reference_model", [True, False])
def test_a_jump_of_the_allocation_meets_no_proportional_kick(reference_model):
    """The hand delivers J^T w at once; the loop's reference follows what the measurement sees of it."""
    gains = TorqueArmGains(
        feedforward="bias",
        force_integral=0.0,
        fusion_tau=0.0,
        stiffness=0.0,
        damping=0.0,
        reference_model=reference_model,
    )
    w0 = np.array([10.0, 0.0, -5.0, 0.0, 0.0, 0.0])
    law, J = _law(gains, w0, limit=np.full(7, 1e6))  # limits out of the way: the budget would scale a kick down
    z = np.zeros(7)
    for _ in range(20):  # settled: the hand delivers w0
        law.torque(0.0, z, z, z, wrench_measured=w0)
    w1 = w0 + np.array([0.0, 0.0, -80.0, 0.0, 0.0, 0.0])  # the allocation presses 80 N more
    law.begin(w1, z, z, z, J, _arm()[1], t_end=0.02, dt=0.01)
    loop = []
    delivered = w0
    for _ in range(5):  # the hand delivers what the last step's torque asked (one step late, as the sensors see it)
        tau = law.torque(0.01, z, z, z, wrench_measured=delivered)
        loop.append(np.linalg.lstsq(J.T, tau - J.T @ w1, rcond=None)[0])
        delivered = np.linalg.lstsq(J.T, tau, rcond=None)[0]
    kick = max(abs(x[2]) for x in loop)
    if reference_model:
        assert kick < 1.0  # N: the feed-forward carries the jump
    else:
        assert kick == pytest.approx(gains.force_feedback * 80.0)  # K times the jump on top of it


def test_a_released_hand_gets_no_force_loop():
    """The force loop controls the wrench on the handle: with the hand let go (`grasped` False) its wrench is not
    applied, so a released arm moves under its feed-forward and posture alone, whatever the loop's gain."""
    gains = TorqueArmGains(feedforward="bias", stiffness=0.0, damping=0.0)
    law, J = _law(gains, np.zeros(6), limit=np.full(7, 1e6))
    z = np.zeros(7)
    loop = np.array([3.0, -1.0, 2.0, 0.1, 0.0, 0.2])
    free = law.torque(0.0, z, z, z, grasped=False)
    np.testing.assert_allclose(law.torque(0.0, z, z, z, loop_wrench=loop, grasped=False), free)
    held = law.torque(0.0, z, z, z, loop_wrench=loop, grasped=True)
    np.testing.assert_allclose(held - free, J.T @ loop, atol=1e-9)
