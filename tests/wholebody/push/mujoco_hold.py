"""A quiet MuJoCo plant of a test's controller set-up and the command that holds each arm and base still, shared by
the MuJoCo plant's tests (one arm and two arms)."""

from __future__ import annotations

import numpy as np

from cart.simulate import MeasurementNoise
from wholebody.push.config import TRUE_CART
from wholebody.push.mujoco_plant import MujocoPlant
from wholebody.push.plant import RobotCommand


def quiet_plant(setup, **kw) -> MujocoPlant:
    """Return the MuJoCo plant of `setup` (`build_controller`'s) on the true cart, without measurement noise unless
    `kw` gives one (`kw`: `MujocoPlant`'s keyword arguments)."""
    kw.setdefault("noise", MeasurementNoise())
    return MujocoPlant(setup.controller.robots, setup.q0, TRUE_CART, **kw)


def hold_commands(plant: MujocoPlant, wrench=np.zeros(6), arm_torque=None) -> list[RobotCommand]:
    """Return one command per robot that holds its arm where it is and its base still, with `wrench` (world-aligned,
    at the grasp) allocated to each hand and `arm_torque` (None: zeros) as the arm's command torque."""
    cmds = []
    for r in plant.measure().robots:
        n = r.q_arm.size
        cmds.append(
            RobotCommand(
                arm_velocity=np.zeros(n),
                arm_position=r.q_arm.copy(),
                arm_torque=np.zeros(n) if arm_torque is None else np.asarray(arm_torque, dtype=float),
                base_twist=np.zeros(3),
                wheel_rates=np.zeros(4),
                hand_wrench=np.asarray(wrench, dtype=float),
            )
        )
    return cmds
