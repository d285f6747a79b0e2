"""The whole-body QP holds a held arm's base at its place behind the cart (`PushController._follow_plan`).

A hand held by the handle does not follow the QP's arm rates (the handle carries it), so a base that the QP lets
lag behind its place in favour of arm motion stays behind, and the arm stretches. Checked on the QP's command for
the Ridgeback + iiwa of a MuJoCo run's controller: its base 2 cm behind its rigid place, the hand on the handle
(Pinocchio IK), the cart moving forward at 0.8 m/s.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wholebody.push import PushConfig
from wholebody.push.base_settings import BasePlanSettings
from wholebody.push.loop import build_controller
from wholebody.push.robot import base_target, grasp_target, solve_grasp_ik

SPEED = 0.8  # m/s, the cart's forward speed
GAP = 0.02  # m, the base behind its place


def base_command(base_plan: BasePlanSettings | None, hand_ahead: float = 0.0) -> tuple[float, float]:
    """Return (commanded forward base speed, the rigid place's speed + base_gain x GAP) of the controller's first
    robot, its base GAP behind its place and its hand `hand_ahead` m ahead of the handle (the grasp's give)."""
    setup = build_controller(PushConfig(trajectory=1, plant="mujoco", contact="fixed", base_plan=base_plan))
    ctrl = setup.controller
    mm, plan = ctrl.robots[0], ctrl.base_plans[0]
    q, qd = np.zeros(3), np.array([SPEED, 0.0, 0.0])
    y = float(ctrl.scheduler.y[0])
    pose, _ = base_target(q, qd, mm.base_offset_b)
    pose[0] -= GAP
    target, _ = grasp_target(q, qd, y, 0.0, mm.R_b_ee, mm.geometry)
    held = pin.SE3(target.rotation, target.translation + np.array([hand_ahead, 0.0, 0.0]))
    mm.x = np.r_[pose, solve_grasp_ik(mm.wb, pose, held, mm.x[3:])]
    cmd, _ = ctrl._robot_command(mm, q, qd, y, 0.0, np.zeros(6), 5.0, plan)
    gain = (base_plan or BasePlanSettings()).base_gain
    return float(cmd.base_twist[0]), SPEED + gain * GAP


@pytest.mark.parametrize("hand_ahead", [0.0, 0.003])
def test_the_base_closes_its_gap_behind_the_cart(hand_ahead):
    speed, asked = base_command(BasePlanSettings(), hand_ahead)
    assert speed > SPEED + 0.5 * (asked - SPEED), (speed, asked)


def test_the_base_pull_is_the_plan_settings():
    weak, _ = base_command(BasePlanSettings(base_weight=1e-3, base_gain=2.0), 0.003)
    firm, _ = base_command(BasePlanSettings(), 0.003)
    assert weak < SPEED < firm, (weak, firm)
