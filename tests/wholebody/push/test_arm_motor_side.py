"""The torque law and its joints: the sensed joint torque from its own command (`TorqueArmGains.motor_torque_tau`),
the joints' damping compensated in the hand's directions while the hand holds (`TorqueArmGains.passive_feedforward`).

The joint's torque is the motor's (the law's command) plus the joint's modelled damping and its unmodelled friction;
the joint torque sensor reads it with white noise. A law on a random 6 x 7 Jacobian and inertia is fed what an arm
holding a constant wrench would sense while its command jumps from step to step.
"""

from __future__ import annotations

import numpy as np
import pytest

from wholebody.push.arm_control import TorqueArmGains, TorqueArmLaw

LIMIT = np.array([320.0, 320.0, 176.0, 176.0, 110.0, 40.0, 40.0])  # the iiwa's effort limits (N m)
DT = 0.002


def _arm() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(11)
    A = rng.normal(size=(7, 7))
    return 0.5 * rng.normal(size=(6, 7)), A @ A.T + 7.0 * np.eye(7)


def _estimates(motor_tau: float, friction: np.ndarray, steps: int = 2000, seed: int = 3) -> np.ndarray:
    """Return the law's hand wrench estimate (joint side alone) at each step, the truth being `TRUTH`.

    Each step the law commands a torque (its posture impedance on a random state: tens of N m that jump every
    step); the joint's torque is that command + the joints' damping (-0.5 v) + `friction` (steps, N m per joint),
    the sensor reads it + white noise (1e-3 of each limit); the model side (M qdd + b) holds the true external
    torque ``-J^T w`` on top of the joint's torque."""
    J, M = _arm()
    gains = TorqueArmGains(feedforward="bias", motor_torque_tau=motor_tau, ft_noise=None, fusion_tau=0.0)
    law = TorqueArmLaw(LIMIT, gains, DT, joint_damping=np.full(7, 0.5))
    z = np.zeros(7)
    law.begin(TRUTH, z, z, z, J, M, t_end=1e9, dt=0.01)
    rng = np.random.default_rng(seed)
    out = []
    for k in range(steps):
        q, v = rng.normal(0.0, 0.1, 7), rng.normal(0.0, 1.0, 7)
        tau = law.torque(0.0, q, v, z)  # what the motor applies this step
        passive = -0.5 * v
        joint = tau + passive + friction[k]
        sensed = joint + 1e-3 * LIMIT * rng.normal(size=7)
        model = -J.T @ TRUTH + joint  # M qdd + b: the external torque plus the joint's own
        law.joint_torque_sample(model - sensed, None, sensed)
        out.append(law.joint_estimate(np.zeros(6)))
    return np.array(out)


TRUTH = np.array([30.0, -5.0, -20.0, 0.0, 0.0, 1.0])


def test_the_command_carries_the_joint_torque_and_the_sensor_only_its_slow_part():
    none = np.zeros((2000, 7))
    raw = _estimates(0.0, none)[200:] - TRUTH
    fused = _estimates(0.05, none)[200:] - TRUTH
    # unbiased: the command's jumps (tens of N m every step) reach the estimate exactly
    assert np.all(np.abs(fused.mean(axis=0)) < 0.1 * raw.std(axis=0))
    # the sensors' white noise passes as sqrt(a / (2 - a)), a = dt / (tau + dt): 0.14 of it at 50 ms
    a = DT / (0.05 + DT)
    ratio = fused[:, :3].std(axis=0) / raw[:, :3].std(axis=0)
    assert np.all(np.abs(ratio / np.sqrt(a / (2.0 - a)) - 1.0) < 0.2)


def test_an_unmodelled_friction_step_is_followed_within_the_low_pass():
    friction = np.zeros((2000, 7))
    friction[1000:, 1] = 2.0  # joint 2 takes 2 N m from t = 2 s on (friction the model does not know)
    est = _estimates(0.05, friction, seed=4)
    J, _ = _arm()
    gains = TorqueArmGains(feedforward="bias", ft_noise=None, fusion_tau=0.0)
    jump = float(np.linalg.norm(TorqueArmLaw(LIMIT, gains, DT)._estimator(J)[0] @ np.r_[0.0, 2.0, 0, 0, 0, 0, 0]))
    just_after = float(np.linalg.norm(est[1002:1006].mean(axis=0) - TRUTH))
    settled = float(np.linalg.norm(est[1300:].mean(axis=0) - TRUTH))  # 12 time constants later
    assert just_after > 0.5 * jump  # the step shows first (the sensor's part lags it) ...
    assert settled < 0.1 * jump  # ... and is gone after the low-pass


def test_the_joints_damping_is_compensated_in_the_hands_directions_while_the_hand_holds():
    """The joint's viscous damping takes ``-D v`` from the motor's torque; with `passive_feedforward` and the hand
    holding, the law gives back its hand-space part: what reaches the links (motor + damping) puts on the held hand
    the wrench of an arm without damping (its acceleration ``J M^-1 tau`` under a held hand is the constraint's), and
    the null space keeps the damping. A released hand keeps all of it (the arm's only damping in free space)."""
    J, M = _arm()
    z = np.zeros(7)
    rng = np.random.default_rng(5)
    q, v, bias = rng.normal(0.0, 0.1, 7), rng.normal(0.0, 1.0, 7), rng.normal(0.0, 5.0, 7)
    D = np.array([0.5, 0.5, 0.5, 0.5, 0.5, 0.2, 0.2])
    passive = -D * v
    taus = {}
    for on, grasped in ((True, True), (True, False), (False, True)):
        law = TorqueArmLaw(LIMIT, TorqueArmGains(passive_feedforward=on), DT, joint_damping=D)
        law.begin(TRUTH, z, z, z, J, M, t_end=0.01, dt=0.01)
        taus[on, grasped] = law.torque(0.0, q, v, bias, grasped=grasped)
    undamped = TorqueArmLaw(LIMIT, TorqueArmGains(), DT)
    undamped.begin(TRUTH, z, z, z, J, M, t_end=0.01, dt=0.01)
    reference = undamped.torque(0.0, q, v, bias)
    held = taus[True, True] + passive - reference  # what the damping leaves on the links
    on_hand = np.linalg.norm(J @ np.linalg.solve(M, passive))  # the damping's own acceleration of a free hand
    np.testing.assert_allclose(J @ np.linalg.solve(M, held), 0.0, atol=1e-6 * on_hand)  # none of it on the hand
    # the null space keeps the damping: N^T (-D v), N^T = I - J^T Jbar^T (an independent computation)
    Minv = np.linalg.inv(M)
    Jbar = Minv @ J.T @ np.linalg.inv(J @ Minv @ J.T)
    np.testing.assert_allclose(held, (np.eye(7) - J.T @ Jbar.T) @ passive, atol=1e-6 * np.abs(passive).max())
    assert np.linalg.norm(held) > 0.1 * np.linalg.norm(passive)  # and that is not nothing
    np.testing.assert_allclose(taus[True, False], reference, atol=1e-9)  # released: all the damping stays
    np.testing.assert_allclose(taus[False, True], reference, atol=1e-9)  # off: the damping is the loop's to meet
    assert np.max(np.abs(passive)) > 0.1  # the test holds a damping worth compensating


def test_joint_damping_must_be_one_non_negative_value_per_joint():
    with pytest.raises(ValueError, match="one damping >= 0 per joint"):
        TorqueArmLaw(LIMIT, joint_damping=np.full(6, 0.5))
    with pytest.raises(ValueError, match="one damping >= 0 per joint"):
        TorqueArmLaw(LIMIT, joint_damping=np.r_[np.full(6, 0.5), -0.1])
