"""The base plan (`wholebody.push.base_plan`) of a differential drive (the WMRA) on Traj. 2's first turn.

Checked independently of the plan's own rows: the sideways speed of each segment from the chord of the planned
poses (a differential drive's step is an arc, whose chord lies along its mean heading: WMRA paper eq. 4-7), the
wheel rates (vx -+ omega L1 / 2) / L5 (paper eq. 4-5), and the arm's mount-wrist distance from Pinocchio's
forward kinematics of the plan's postures, which must put the hand on the handle of the desired cart.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import robots
from cart.trajectories import Turn, UnicycleTrajectory
from wholebody.push.base_plan import body_twists, plan_base, rigid_poses
from wholebody.push.base_settings import BasePlanSettings
from wholebody.push.robot import base_target, grasp_target, make_robots

from tests.wholebody.push.test_base_plan import world_poses  # the same first turn (FIRST_TURN)

#: Traj. 2's first turn (pi/2 over 3 s at 0.8 m/s from t = 7 s), the motion held after 13 s
FIRST_TURN = UnicycleTrajectory(duration=13.0, stop_start=13.0, turns=(Turn(7.0, 3.0, math.pi / 2),))
STRAIGHT = UnicycleTrajectory(duration=13.0, stop_start=13.0, turns=())
CONTACT_Y = 0.1
SETTINGS = BasePlanSettings(step=0.2, lead=1.0, tail=2.0)


@pytest.fixture(scope="module")
def robot_and_plan():
    mm = make_robots(robots.load("wmra"), np.zeros(3), [CONTACT_Y])[0]
    return mm, plan_base(mm, FIRST_TURN, CONTACT_Y, SETTINGS)


def sideways_speed(poses: np.ndarray, h: float) -> np.ndarray:
    """Return each segment's speed across its mean heading, from its chord (m/s)."""
    d = np.diff(poses[:, :2], axis=0)
    mid = 0.5 * (poses[1:, 2] + poses[:-1, 2])
    return (np.cos(mid) * d[:, 1] - np.sin(mid) * d[:, 0]) / h


def test_the_rigid_place_moves_the_base_sideways_in_the_turn(robot_and_plan):
    mm, _ = robot_and_plan
    t = np.arange(6.0, 12.0, 0.2)
    cart = np.array([FIRST_TURN.sample(float(v))[0] for v in t])
    assert np.abs(sideways_speed(rigid_poses(cart, mm.base_offset_b), 0.2)).max() > 0.5


def test_a_straight_push_is_planned_as_the_rigid_place(robot_and_plan):
    mm, _ = robot_and_plan
    plan = plan_base(mm, STRAIGHT, CONTACT_Y, SETTINGS)
    assert plan.times == ()
    q, qd = STRAIGHT.sample(5.0)[:2]
    for got, want in zip(plan.target(5.0, q, qd, mm.base_offset_b), base_target(q, qd, mm.base_offset_b)):
        np.testing.assert_allclose(got, want)


def test_plan_has_no_sideways_speed_and_keeps_the_wheels_within_their_limits(robot_and_plan):
    mm, plan = robot_and_plan
    assert len(plan.times) == 1 and plan.times[0][0] <= 7.0 and plan.times[0][-1] >= 10.0
    _, base = world_poses(plan, 0)
    assert np.abs(sideways_speed(base, SETTINGS.step)[1:-1]).max() < 1e-3  # the first and last: rigid knots
    tw = body_twists(base, SETTINGS.step)
    r, half = mm.wb.base.wheel_radius, 0.5 * mm.wb.base.track
    wheels = np.c_[tw[:, 0] - half * tw[:, 2], tw[:, 0] + half * tw[:, 2]] / r
    assert np.abs(wheels).max() <= float(np.min(mm.wb.wheel_velocity_limit)) + 1e-3
    assert np.abs(np.diff(wheels, axis=0)).max() / SETTINGS.step <= mm.profile.wheel_acceleration_limit + 1e-2
    assert np.abs(base[:, 2] - world_poses(plan, 0)[0][:, 2]).max() > 0.2  # the base turns off the cart's heading


def test_plan_postures_hold_the_handle_within_the_arm_reach(robot_and_plan):
    mm, plan = robot_and_plan
    cart, base = world_poses(plan, 0)
    wb, data = mm.wb, mm.wb.model.createData()
    ids = [wb.model.getJointId(n) for n in wb.arm_joints]
    for q, p, qa in zip(cart, base, plan.postures[0]):
        x = np.r_[p, qa]
        target, _ = grasp_target(q, np.zeros(3), CONTACT_Y, 0.0, mm.R_b_ee, mm.geometry)
        assert np.linalg.norm(wb.ee_placement(x).translation - target.translation) < 1e-4
        pin.forwardKinematics(wb.model, data, wb.to_pinocchio_q(x))
        reach = np.linalg.norm(data.oMi[ids[-2]].translation[:2] - data.oMi[ids[0]].translation[:2])
        assert SETTINGS.min_reach_fraction * plan.nominal_stretch - 1e-3 <= reach <= plan.stretch[0] + 1e-3
