"""The admittance law of a velocity-servoed arm, without physics: what its setpoints make the servos apply.

A servo of damping ``k_v`` applies ``k_v (qdot_set - qdot)``; with the hand held (the arm's velocity what the cart and
the base make it) the law's setpoint is that velocity plus the torque it wants, over ``k_v``.
"""

from __future__ import annotations

import numpy as np
import pytest

from wholebody.push.admittance_law import AdmittanceArmLaw, AdmittanceGains
from wholebody.push.arm_control import hand_inertia_terms

KV = np.array([60.0, 60.0, 30.0, 30.0, 15.0, 10.0, 10.0])
DT = 0.01


def _arm(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(6, 7)), rng.normal(size=7)


def _torque(law: AdmittanceArmLaw, J, q, w, w_meas, v=None, plan=None, bias=None) -> np.ndarray:
    """Return the servos' torque at the period's start: ``k_v (qdot_set - v)`` (arm held at the plan's posture)."""
    v = np.zeros(7) if v is None else v
    plan = np.zeros(7) if plan is None else plan
    qdot_set = law.velocity(plan, q, q, v, J, w, w_meas, DT, bias=bias)
    return KV * (qdot_set - v)


def test_with_no_error_the_servos_apply_the_push_whatever_the_arm_moves():
    J, q = _arm()
    law = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV), plan_acceleration=False))
    w = np.array([10.0, -3.0, -5.0, 0.2, 0.0, 0.5])
    v = J.T @ np.linalg.solve(J @ J.T, np.array([0.3, 0.1, 0.0, 0.0, 0.0, 0.2]))  # the hand moves with the cart
    assert _torque(law, J, q, w, w, v=v) == pytest.approx(J.T @ w, rel=1e-3, abs=1e-3)


def test_the_loop_compares_the_hand_with_the_last_periods_allocation():
    """A jump of the allocation is the feed-forward's: the loop sees only what the hand did not deliver."""
    J, q = _arm(1)
    law = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV), integral_gain=0.0))
    w0, w1 = np.array([5.0, 0, 0, 0, 0, 0]), np.array([40.0, 0, -20.0, 0, 0, 0])
    _torque(law, J, q, w0, w0)
    assert _torque(law, J, q, w1, w0) == pytest.approx(J.T @ w1, rel=1e-3, abs=1e-3)  # the hand delivered w0: no error
    short = w1 - np.array([4.0, 0, 0, 0, 0, 0])
    L = law.gains.loop_gain
    assert _torque(law, J, q, w1, short) == pytest.approx(J.T @ (w1 + L * (w1 - short)), rel=1e-3, abs=1e-3)


def test_the_measured_wrench_is_the_mean_of_the_samples():
    J, q = _arm(2)
    law = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV), integral_gain=0.0))
    w = np.array([10.0, 0, 0, 0, 0, 0])
    _torque(law, J, q, w, w)
    for k in range(5):  # noisy samples around 8 N
        law.sample(np.array([8.0 + (k - 2), 0, 0, 0, 0, 0]))
    ignored = np.array([100.0, 0, 0, 0, 0, 0])
    L = law.gains.loop_gain
    assert _torque(law, J, q, w, ignored) == pytest.approx(
        J.T @ (w + L * np.array([2.0, 0, 0, 0, 0, 0])), rel=1e-3, abs=1e-3
    )


def test_the_integral_removes_a_steady_shortfall_and_holds_when_the_limits_bind():
    J, q = _arm(3)
    law = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV)), effort_limit=np.full(7, 1e3))
    w = np.array([10.0, 0, 0, 0, 0, 0])
    _torque(law, J, q, w, w)
    first = _torque(law, J, q, w, w - np.array([1.0, 0, 0, 0, 0, 0]))
    later = _torque(law, J, q, w, w - np.array([1.0, 0, 0, 0, 0, 0]))
    assert np.linalg.norm(later - J.T @ w) > np.linalg.norm(first - J.T @ w)  # the integral grows
    tight = np.abs(J.T @ w) * 1.01 + 1e-3  # the push alone nearly fills the limits
    held = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV)), effort_limit=tight)
    _torque(held, J, q, w, w)
    tau = _torque(held, J, q, w, w - np.array([5.0, 0, 0, 0, 0, 0]))
    assert np.all(np.abs(tau) <= tight + 1e-9) and held.budget < 1.0
    assert np.all(held._integral == 0.0)  # anti-windup


def test_the_plans_change_of_velocity_goes_into_the_predicted_motion():
    J, q = _arm(4)
    law = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV), integral_gain=0.0))
    w = np.zeros(6)
    _torque(law, J, q, w, w, plan=np.zeros(7))
    dv = J.T @ np.linalg.solve(J @ J.T, np.array([0.01, 0, 0, 0, 0, 0]))  # the plan speeds the hand up by 1 cm/s
    tau = _torque(law, J, q, w, w, plan=dv)
    assert J @ (tau / KV) == pytest.approx(J @ dv, rel=1e-3, abs=1e-3)


def _inertia(seed: int, n: int = 7) -> np.ndarray:
    """Return a joint-space inertia (n x n, symmetric positive definite)."""
    A = np.random.default_rng(seed).normal(size=(n, n))
    return A @ A.T + 0.5 * np.eye(n)


def _inertial_terms(seed: int, a_hand: np.ndarray, a_base: np.ndarray):
    """Return a robot (arm J_a, base J_b, inertia M over arm then base joints, Jdot qdot) and the law's ``inertial``."""
    rng = np.random.default_rng(seed)
    J_a, J_b, jdq = rng.normal(size=(6, 7)), rng.normal(size=(6, 3)), rng.normal(size=6)
    M = _inertia(seed, 10)
    t, K = hand_inertia_terms(M[:7, :7], M[:7, 7:], J_a, J_b, jdq, a_hand)
    return (J_a, J_b, M, jdq), (t, K, a_base)


def test_the_servos_add_the_torque_that_moves_the_arm_with_the_hand_and_the_base():
    """The added torque, on the arm's rows of the robot's dynamics (the hand's wrench aside), gives the hand the
    predicted acceleration while the base accelerates as planned."""
    a, a_base = np.array([0.4, -0.2, 0.0, 0.0, 0.0, 0.3]), np.array([0.3, 0.1, -0.2])
    (J, J_b, M, jdq), inertial = _inertial_terms(5, a, a_base)
    q, w = np.zeros(7), np.array([10.0, -3.0, -5.0, 0.2, 0.0, 0.5])
    law = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV), integral_gain=0.0, hand_inertia=True))
    tau = KV * law.velocity(np.zeros(7), q, q, np.zeros(7), J, w, w, DT, inertial=inertial) - J.T @ w
    qdd = np.linalg.solve(M[:7, :7], tau - M[:7, 7:] @ a_base)
    assert J @ qdd + J_b @ a_base + jdq == pytest.approx(a, rel=1e-6, abs=1e-6)
    off = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV), integral_gain=0.0))  # the default: off
    plain = off.velocity(np.zeros(7), q, q, np.zeros(7), J, w, w, DT, inertial=inertial)
    assert KV * plain == pytest.approx(J.T @ w, rel=1e-6, abs=1e-9)


def test_the_arms_inertia_stays_within_the_limits_the_push_and_its_load_leave():
    (J, _, _, _), inertial = _inertial_terms(6, np.array([5.0, 0, 0, 0, 0, 2.0]), np.array([1.0, 0.0, 0.5]))
    q, w, bias = np.zeros(7), np.array([10.0, 0, 0, 0, 0, 0]), np.full(7, 0.5)
    limit = np.abs(J.T @ w + bias) + 0.05  # 0.05 N m of room on every joint
    law = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV), hand_inertia=True), effort_limit=limit)
    short = w - np.array([2.0, 0, 0, 0, 0, 0])  # the loop has an error to correct
    tau = KV * law.velocity(np.zeros(7), q, q, np.zeros(7), J, w, short, DT, bias=bias, inertial=inertial) + bias
    assert np.all(np.abs(tau) <= limit + 1e-9)
    assert np.max(np.abs(tau) - limit) > -1e-9  # the inertia fills the room on one joint
    assert law.budget == 0.0  # none left for the loop


def test_inertial_terms_of_the_wrong_shape_are_refused():
    J, q = _arm(7)
    law = AdmittanceArmLaw(7, AdmittanceGains(servo_kv=tuple(KV), hand_inertia=True))
    w = np.zeros(6)
    with pytest.raises(ValueError, match="inertial"):
        law.velocity(np.zeros(7), q, q, np.zeros(7), J, w, w, DT, inertial=(np.zeros(6), np.zeros((6, 3)), np.zeros(3)))
