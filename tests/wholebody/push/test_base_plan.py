"""The base plan (`wholebody.push.base_plan`) on Traj. 2's first turn: within the wheel limits, the arm in reach.

Checked independently of the plan's own rows: the mecanum rim speed |vx| + |vy| + (lx + ly)|omega| from the
planned poses by finite differences, and the arm's shoulder-wrist distance from Pinocchio's forward kinematics of
the plan's postures, which must put the hand on the handle of the desired cart.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import robots
from cart.trajectories import Turn, UnicycleTrajectory
from wholebody.push.base_plan import BasePlan, elbow_joint, plan_base, rigid_poses
from wholebody.push.base_settings import BasePlanSettings
from wholebody.push.robot import grasp_target, make_robots

#: Traj. 2's first turn (pi/2 over 3 s at 0.8 m/s from t = 7 s), the motion held after 13 s
FIRST_TURN = UnicycleTrajectory(duration=13.0, stop_start=13.0, turns=(Turn(7.0, 3.0, math.pi / 2),))
CONTACT_Y = -0.2
SETTINGS = BasePlanSettings(step=0.2, lead=1.0, tail=2.0)


@pytest.fixture(scope="module")
def robot_and_plan():
    mm = make_robots(robots.load("ridgeback_iiwa"), np.zeros(3), [CONTACT_Y])[0]
    return mm, plan_base(mm, FIRST_TURN, CONTACT_Y, SETTINGS)


def rim_speed(poses: np.ndarray, h: float, half_span: float) -> np.ndarray:
    """Return the largest mecanum rim speed |vx| + |vy| + half_span |omega| of each segment (body twist at the
    segment's start heading, world displacement / h)."""
    d = np.diff(poses, axis=0) / h
    c, s = np.cos(poses[:-1, 2]), np.sin(poses[:-1, 2])
    vx, vy = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
    return np.abs(vx) + np.abs(vy) + half_span * np.abs(d[:, 2])


def world_poses(plan: BasePlan, i: int, trajectory=FIRST_TURN) -> tuple[np.ndarray, np.ndarray]:
    """Return (cart poses, base poses) of window i of the plan of `trajectory`, in the world."""
    cart = np.array([trajectory.sample(float(t))[0] for t in plan.times[i]])
    cart[:, 2] = np.unwrap(cart[:, 2])
    rel = plan.relative[i]
    c, s = np.cos(cart[:, 2]), np.sin(cart[:, 2])
    base = np.c_[cart[:, 0] + c * rel[:, 0] - s * rel[:, 1], cart[:, 1] + s * rel[:, 0] + c * rel[:, 1]]
    return cart, np.c_[base, cart[:, 2] + rel[:, 2]]


def half_span(mm) -> float:
    """Return lx + ly of the mecanum base: its wheel rate per unit yaw rate times the wheel radius."""
    return float(abs(mm.wb.base.twist_to_wheels()[0, 2]) * mm.wb.base.wheel_radius)


def test_rigid_place_breaks_the_wheel_limit_in_the_turn(robot_and_plan):
    mm, _ = robot_and_plan
    t = np.arange(6.0, 12.0, 0.1)
    cart = np.array([FIRST_TURN.sample(float(v))[0] for v in t])
    rim = rim_speed(rigid_poses(cart, mm.base_offset_b), 0.1, half_span(mm))
    assert rim.max() > 2.0 * mm.wb.base.wheel_radius * float(np.min(mm.wb.wheel_velocity_limit))


def test_plan_keeps_the_wheels_within_their_limit(robot_and_plan):
    mm, plan = robot_and_plan
    assert len(plan.times) == 1 and plan.times[0][0] <= 7.0 and plan.times[0][-1] >= 10.0
    assert_within_the_wheel_limit(mm, world_poses(plan, 0)[1])


def assert_within_the_wheel_limit(mm, base: np.ndarray) -> None:
    """Assert every segment of the base poses (k, 3) keeps its mecanum rims within their speed limit."""
    rim_limit = mm.wb.base.wheel_radius * float(np.min(mm.wb.wheel_velocity_limit))
    # the plan bounds each segment at its mean heading; at its start heading the body twist is turned by half the
    # segment's heading change, which moves |vx| + |vy| by at most sqrt(2) |v| |dtheta| / 2
    d = np.diff(base, axis=0)
    slack = math.sqrt(2.0) * np.linalg.norm(d[:, :2], axis=1) / SETTINGS.step * np.abs(d[:, 2]) / 2.0
    assert np.all(rim_speed(base, SETTINGS.step, half_span(mm)) <= rim_limit + slack + 1e-6)


def test_a_run_that_ends_in_the_turn_plans_to_its_end_within_the_wheel_limits(robot_and_plan):
    """The run's end cuts the window: its last knots are free (the rigid place there breaks the wheel limits)."""
    mm, _ = robot_and_plan
    cut = UnicycleTrajectory(duration=8.5, stop_start=13.0, turns=(Turn(7.0, 3.0, math.pi / 2),))
    plan = plan_base(mm, cut, CONTACT_Y, SETTINGS)
    assert len(plan.times) == 1 and plan.times[0][-1] == pytest.approx(8.4)
    assert_within_the_wheel_limit(mm, world_poses(plan, 0, cut)[1])


def test_plan_postures_hold_the_handle_with_a_bent_elbow(robot_and_plan):
    mm, plan = robot_and_plan
    cart, base = world_poses(plan, 0)
    wb, data = mm.wb, mm.wb.model.createData()
    ids = [wb.model.getJointId(n) for n in wb.arm_joints]
    pin.forwardKinematics(wb.model, data, wb.to_pinocchio_q(mm.x))
    chain = [data.oMi[i].translation.copy() for i in ids[1:-1]]  # shoulder to wrist centre
    full = sum(float(np.linalg.norm(b - a)) for a, b in zip(chain[:-1], chain[1:]))  # the arm stretched
    j = elbow_joint(mm)
    for q, p, qa in zip(cart, base, plan.postures[0]):
        x = np.r_[p, qa]
        target, _ = grasp_target(q, np.zeros(3), CONTACT_Y, 0.0, mm.R_b_ee, mm.geometry)
        assert np.linalg.norm(wb.ee_placement(x).translation - target.translation) < 1e-4
        pin.forwardKinematics(wb.model, data, wb.to_pinocchio_q(x))
        stretch = np.linalg.norm(data.oMi[ids[-2]].translation - data.oMi[ids[1]].translation)
        assert stretch < 0.97 * full
        assert abs(qa[j]) > 0.5


def test_cli_base_plan_flag_sets_the_plan():
    """`cartpush push --base-plan` asks the loop for the base plan with its default settings; `off`, none; without
    it, "auto": planned on the MuJoCo plant only."""
    import argparse
    from dataclasses import replace

    from cartpush.cli import push

    parser = argparse.ArgumentParser()
    push.register(parser.add_subparsers())
    on = push.config_from_args(parser.parse_args(["push", "--base-plan"]))
    off = push.config_from_args(parser.parse_args(["push", "--base-plan", "off"]))
    auto = push.config_from_args(parser.parse_args(["push"]))
    assert on.base_plan == BasePlanSettings()
    assert off.base_plan is None and off.plan_settings() is None
    assert auto.base_plan == "auto" and auto.plan_settings() is None  # the kinematic plant
    assert replace(auto, plant="mujoco", contact="fixed").plan_settings() == BasePlanSettings()


def test_cli_grip_torque_arm_reaches_the_allocation():
    """`--grip-torque-arm M` sets the allocation's GraspModel.torque_arm; a bad value is an OptionError (exit 2)."""
    import argparse

    import pytest

    from cartpush.cli import push
    from cartpush.cli.options import OptionError
    from wholebody.contacts.allocation import ArmLimits
    from wholebody.push import PushConfig

    parser = argparse.ArgumentParser()
    push.register(parser.add_subparsers())
    firm = push.config_from_args(parser.parse_args(["push", "--grip-torque-arm", "0.1"]))
    default = push.config_from_args(parser.parse_args(["push"]))
    assert firm.arm_limits.grasp is not None and firm.arm_limits.grasp.torque_arm == 0.1
    assert default.arm_limits == PushConfig().arm_limits != ArmLimits()  # the loop's 200 N grip
    assert default.arm_limits.grasp is not None
    assert firm.arm_limits.grasp.grip_force == default.arm_limits.grasp.grip_force == 200.0
    for bad in ("-0.1", "nan", "2"):
        with pytest.raises(OptionError, match="--grip-torque-arm"):
            push.config_from_args(parser.parse_args(["push", "--grip-torque-arm", bad]))
