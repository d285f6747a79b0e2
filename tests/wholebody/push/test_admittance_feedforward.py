"""The admittance law applies the allocated wrench: physics of the WMRA's velocity-servoed arm (MuJoCo plant).

The cart is held still (a viscous clamp on its free joint) so the hand's wrench on it is what the arm makes of the
command, and the period-mean of the noise-free F/T is compared with the allocated wrench. The servos' torque is
``k_v (qdot_set - qdot)``: with the push fed forward (``J^T w / k_v`` in the setpoint) it holds ``J^T w`` from the
first period; the admittance alone (loop gain ``A k_v (J J^T)^-1``, about 0.2 here) delivers a fraction of it and
its integral adds the rest over seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

from cart.simulate import MeasurementNoise
from wholebody.push import PushConfig, build_controller
from wholebody.push.admittance_law import AdmittanceGains
from wholebody.push.config import TRUE_CART
from wholebody.push.mujoco_plant import MujocoPlant, MujocoPlantConfig
from wholebody.push.plant import RobotCommand

PUSH = np.array([10.0, 0.0, -5.0, 0.0, 0.0, 0.0])  # world-aligned at the grasp: forward and down
NO_NOISE = MeasurementNoise(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def setup():
    return build_controller(PushConfig(trajectory=1, duration=2.0, robot="wmra", plant="mujoco", contact="fixed"))


def _mean_force_error(setup, gains: AdmittanceGains, duration: float = 0.3) -> float:
    """Return |period-mean hand force - allocated| (N) over the held cart's last 0.1 s of `duration`."""
    plant = MujocoPlant(
        setup.controller.robots, setup.q0, TRUE_CART, noise=NO_NOISE, config=MujocoPlantConfig(admittance=gains)
    )
    c = plant.scene.cart_dof  # a viscous clamp on the cart's free joint
    plant.scene.model.dof_damping[c : c + 6] = 1e5
    errors = []
    for _ in range(int(round(duration / plant.dt))):
        r = plant.measure().robots[0]
        n = r.q_arm.size
        cmd = RobotCommand(
            arm_velocity=np.zeros(n),
            arm_position=r.q_arm.copy(),  # the null-space posture follows the arm: no pull on the hand
            arm_torque=np.zeros(n),
            base_twist=np.zeros(3),
            wheel_rates=np.zeros(2),
            hand_wrench=PUSH,
        )
        plant.step([cmd])
        errors.append(plant._hand_clean[0][:3] - PUSH[:3])
    return float(np.linalg.norm(np.mean(errors[-10:], axis=0)))


def test_the_push_fed_through_the_servos_is_delivered_at_once(setup):
    with_ff = _mean_force_error(setup, AdmittanceGains())
    without = _mean_force_error(setup, AdmittanceGains(servo_kv=0.0, from_arm=False))
    push = float(np.linalg.norm(PUSH[:3]))
    assert with_ff < 0.15 * push  # measured 0.9 of 11.2 N
    assert without > 0.3 * push  # the admittance alone: 8.3 N short after 0.3 s
