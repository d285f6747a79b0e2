"""A differential base whose URDF turns a wheel about -y (a mirrored wheel frame) rolls forward on the MuJoCo
plant as one whose wheels both turn about +y: the wheel servos carry the axis' sign (`mujoco_scene`)."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tests.robots.profile_files import wmra_variant
from wholebody.push import PushConfig, build_controller
from wholebody.push.mujoco_plant import MujocoPlant

ROBOTS = Path(__file__).resolve().parents[3] / "robots"
RIGHT_WHEEL = '<joint name="wheel_right_joint" type="continuous">'


def _mirrored_wmra(folder: Path) -> str:
    """Write the WMRA with its right wheel's joint turned about -y (same wheel, opposite axis) and its profile."""
    text = (ROBOTS / "wmra.urdf").read_text()
    start = text.index(RIGHT_WHEEL)
    end = text.index("</joint>", start)
    joint = text[start:end]
    assert '<axis xyz="0 0 1"/>' in joint
    text = text[:start] + joint.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 -1"/>') + text[end:]
    return wmra_variant(folder, "wmra_mirrored", text)


def _drive_both_wheels(robot: str, rate: float = 3.0, seconds: float = 1.0) -> tuple[np.ndarray, float]:
    """Return (displacement in the base's start frame, yaw change) of the base after both wheels are servoed at
    `rate` rad/s (forward-positive) for `seconds`, the grasp released and the arm held against gravity."""
    setup = build_controller(PushConfig(trajectory=1, contact="fixed", robot=robot))
    plant = MujocoPlant(setup.controller.robots, setup.q0, PushConfig().true_params, seed=0)
    m, d, r = plant.scene.model, plant.scene.data, plant.scene.robots[0]
    d.eq_active[r.weld] = 0
    x0, rot0 = d.xpos[r.root_body].copy(), d.xmat[r.root_body].reshape(3, 3).copy()
    for _ in range(int(round(seconds / m.opt.timestep))):
        d.ctrl[r.arm_actuators] = 0.0
        hold = r.arm_hold_actuators if len(r.arm_hold_actuators) else r.arm_actuators
        d.ctrl[hold] = d.qfrc_bias[r.arm_dof]
        d.ctrl[r.wheel_actuators] = rate
        mujoco.mj_step(m, d)
    rot = d.xmat[r.root_body].reshape(3, 3)
    yaw = math.atan2(rot[1, 0], rot[0, 0]) - math.atan2(rot0[1, 0], rot0[0, 0])
    return rot0.T @ (d.xpos[r.root_body] - x0), yaw


def test_a_wheel_turning_about_minus_y_rolls_the_base_forward_like_its_mirror(tmp_path):
    moved, yaw = _drive_both_wheels("wmra")
    moved_m, yaw_m = _drive_both_wheels(_mirrored_wmra(tmp_path))
    assert moved[0] > 0.2  # both wheels at 3 rad/s on 0.17 m tyres: about 0.5 m/s, with the start-up
    assert abs(yaw) < math.radians(1.0)
    assert moved_m[0] == pytest.approx(moved[0], rel=0.02)
    assert abs(yaw_m) < math.radians(1.0)
