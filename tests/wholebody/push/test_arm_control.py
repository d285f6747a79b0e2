"""The torque arm law's budget and its force loop's reference (`wholebody.push.arm_control.TorqueArmLaw`).

No physics here: a law on a random 6 x 7 Jacobian and inertia, fed states and readings directly.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from wholebody.push.arm_control import TorqueArmGains, TorqueArmLaw, torque_budget

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


def test_budget_keeps_the_task_part_and_scales_the_hands_feedback_into_the_limits():
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
    # the task part whole, the loop scaled as one: tau - task is parallel to asked - task (a clip would bend it)
    s = float(np.dot(tau - task, asked - task) / np.dot(asked - task, asked - task))
    assert 0.0 < s < 1.0
    np.testing.assert_allclose(tau, task + s * (asked - task), atol=1e-9)
    np.testing.assert_allclose(law.peak_task_ratio, np.max(np.abs(task) / LIMIT))
    np.testing.assert_allclose(law.peak_joint_ratio, np.abs(tau) / LIMIT)
    clipped, _ = _law(replace(gains, budget=False), w)  # the default: the sum clipped, each joint's full effort
    np.testing.assert_allclose(
        clipped.torque(0.0, z, z, bias, wrench_measured=reading), np.clip(asked, -LIMIT, LIMIT), atol=1e-9
    )
    assert clipped.peak_ratio > 1.0 and clipped.saturated_steps == 1


def test_posture_takes_the_room_the_hands_terms_leave_each_joint():
    w = np.array([20.0, -5.0, -40.0, 0.0, 0.0, 2.0])
    law, J = _law(TorqueArmGains(feedforward="bias", null_space=False, budget=True), w)
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


def test_law_counts_a_clip_when_the_task_part_exceeds():
    w = np.array([0.0, 0.0, -50.0, 0.0, 0.0, 0.0])
    law, J = _law(TorqueArmGains(feedforward="bias", force_feedback=0.0, budget=True), w, limit=np.full(7, 1e-3))
    z = np.zeros(7)
    tau = law.torque(0.0, z, z, z)
    assert np.all(np.abs(tau) <= 1e-3 + 1e-12)
    assert law.saturated_steps == 1 and law.peak_ratio > 1.0 and law.peak_task_ratio == law.peak_ratio


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
