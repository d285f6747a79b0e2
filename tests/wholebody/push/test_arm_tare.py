"""The torque law zeroes its sensors while the arm holds still before the push (`TorqueArmLaw.hold`,
`TorqueArmLaw.tare`; the MuJoCo plant's settling, `MujocoPlantConfig.tare`).

The loop's measured wrench takes two slow parts from the sensors (the joint torque sensors' over
`TorqueArmGains.motor_torque_tau`, the F/T's per-joint correction over `TorqueArmGains.fusion_tau`), each the running
mean of its samples so far at first. Started at the push, the first correction is one F/T sample (3 N of noise per
axis) and the hand's measured wrench carries it; started over a hold, it is the mean of the hold's samples.
"""

from __future__ import annotations

import numpy as np

from wholebody.push.arm_control import TorqueArmGains, TorqueArmLaw

LIMIT = np.array([320.0, 320.0, 176.0, 176.0, 110.0, 40.0, 40.0])  # the iiwa's effort limits (N m)
DT = 0.002
TRUTH = np.array([30.0, -5.0, -20.0, 0.0, 0.0, 1.0])
FT_NOISE = 3.0
HOLD = 100  # physics steps held before the push (the plant's 0.2 s of settling at 500 Hz)


def _arm() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(11)
    A = rng.normal(size=(7, 7))
    return 0.5 * rng.normal(size=(6, 7)), A @ A.T + 7.0 * np.eye(7)


class _Sensors:
    """An arm holding the wrench `TRUTH` on the handle: joint torque sensors with an offset (1 % of each limit) and
    white noise (0.1 %), an F/T with white noise, the model side ``M qdd + b`` exact."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.offset = 0.01 * LIMIT * self.rng.normal(size=7)
        self.J, _ = _arm()

    def sample(self, law: TorqueArmLaw, tau: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Give `law` the joint torques of a step commanded `tau` at velocity `v`; return the step's F/T reading."""
        joint = tau - 0.5 * v
        sensed = joint - self.offset + 1e-3 * LIMIT * self.rng.normal(size=7)
        law.joint_torque_sample(-self.J.T @ TRUTH + joint - sensed, None, sensed)
        return TRUTH + np.r_[self.rng.normal(0.0, FT_NOISE, 3), np.zeros(3)]


def _push_errors(tared: bool, seed: int, steps: int = 50) -> np.ndarray:
    """Return the loop's measured force minus the truth over the push's first `steps` physics steps."""
    J, M = _arm()
    law = TorqueArmLaw(LIMIT, TorqueArmGains(), DT, joint_damping=np.full(7, 0.5))
    arm = _Sensors(seed)
    z = np.zeros(7)
    ft = TRUTH + np.r_[arm.rng.normal(0.0, FT_NOISE, 3), np.zeros(3)]
    if tared:
        for _ in range(HOLD):
            v = arm.rng.normal(0.0, 0.01, 7)
            law.hold(J, z, v)
            law.tare(arm.sample(law, z, v))
    law.begin(TRUTH, z, z, z, J, M, t_end=1.0, dt=0.01)
    out = []
    for _ in range(steps):
        v = arm.rng.normal(0.0, 0.01, 7)
        e = law.force_error(ft)  # the reference is TRUTH: e = TRUTH - w_f
        tau = law.torque(0.0, z, v, z, loop_wrench=law.force_loop(e))
        ft = arm.sample(law, tau, v)
        out.append(-e[:3])
    return np.array(out)


def test_a_hold_before_the_push_takes_the_ft_noise_out_of_the_first_correction():
    cold = np.concatenate([_push_errors(False, s) for s in range(8)])
    tared = np.concatenate([_push_errors(True, s) for s in range(8)])
    rms_cold = float(np.sqrt(np.mean(cold**2)))
    rms_tared = float(np.sqrt(np.mean(tared**2)))
    # the running mean of n F/T samples carries FT_NOISE / sqrt(n) per axis: over the hold, n >= HOLD
    assert rms_tared < 2.0 * FT_NOISE / np.sqrt(HOLD)
    assert rms_tared < 0.5 * rms_cold
    # and the joints' offsets (1 % of each limit: tens of N at the hand) are out from the push's first step
    assert float(np.abs(tared[:5]).max()) < 1.0


def test_tare_leaves_the_loop_alone():
    """A hold moves no state of the loop itself: the measured wrench's filter and the integral start at the push."""
    J, _ = _arm()
    law = TorqueArmLaw(LIMIT, TorqueArmGains(), DT, joint_damping=np.full(7, 0.5))
    arm = _Sensors(0)
    z = np.zeros(7)
    for _ in range(10):
        law.hold(J, z, z)
        law.tare(arm.sample(law, z, z))
    assert law._w_f is None and law._w_ref is None
    np.testing.assert_array_equal(law._integral, np.zeros(6))
