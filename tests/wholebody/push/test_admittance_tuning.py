"""The velocity-servo arm's gains from its own limits: servo damping per joint and the admittance's loop gain."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from wholebody.push.admittance_tuning import (
    LOOP_GAIN,
    arm_tuning,
    loop_admittance,
    loop_gains,
    servo_damping,
    set_servo_damping,
)

#: TIAGo's arm (example-robot-data's tiago_no_hand.urdf): effort (N m) and speed (rad/s) limits of arm_1..7
TIAGO_EFFORT = np.array([39.0, 39.0, 17.86, 17.86, 3.0, 6.6, 6.6])
TIAGO_SPEED = np.array([2.7, 3.66, 4.58, 4.58, 1.95, 1.76, 1.76])


def test_each_joints_servo_reaches_its_effort_limit_at_its_speed_limit():
    kv = servo_damping(TIAGO_EFFORT, TIAGO_SPEED, kv_max=80.0)
    assert kv == pytest.approx(TIAGO_EFFORT / TIAGO_SPEED)
    assert kv[4] == pytest.approx(3.0 / 1.95)  # the 3 N m wrist: 1.5 N m s/rad, not 80


def test_the_servo_damping_is_capped_and_a_joint_without_limits_gets_the_cap():
    kv = servo_damping(np.array([60.0, np.inf, 10.0, 0.0]), np.array([0.5, 1.0, np.inf, 1.0]), kv_max=80.0)
    assert kv.tolist() == [80.0, 80.0, 80.0, 80.0]
    with pytest.raises(ValueError, match="kv_max"):
        servo_damping(np.array([np.inf]), np.array([1.0]))


def test_the_loop_gain_is_the_target_in_every_direction_whatever_the_arm():
    rng = np.random.default_rng(3)
    for scale in (0.2, 1.0):  # a short arm (TIAGo's) and a long one: task-space damping 25x apart
        J = scale * rng.normal(size=(6, 7))
        J[3:] /= scale  # the rotation rows do not scale with the arm's length
        kv = servo_damping(TIAGO_EFFORT, TIAGO_SPEED, 80.0)
        gains = loop_gains(J, kv, loop_admittance(J, kv, 0.3))
        assert gains == pytest.approx(np.full(6, 0.3))


def test_one_diagonal_admittance_gives_each_arm_its_own_loop_gains():
    """What the derived admittance replaces: a diagonal A's loop gains follow the arm's task-space damping."""
    rng = np.random.default_rng(4)
    J = rng.normal(size=(6, 7))
    A = np.diag([1e-3] * 3 + [5e-3] * 3)
    spread = loop_gains(J, np.full(7, 80.0), A)
    short = loop_gains(np.r_[0.2 * J[:3], J[3:]], np.full(7, 80.0), A)
    assert spread[-1] / spread[0] > 3.0
    assert short[-1] > 2.0 * spread[-1]  # the shorter arm's loop is stiffer by its smaller lever


def test_arm_tuning_defaults_to_the_loop_gain_constant():
    t = arm_tuning(TIAGO_EFFORT, TIAGO_SPEED, 80.0)
    assert t.loop_gain == LOOP_GAIN and t.kv.shape == (7,)
    assert arm_tuning(TIAGO_EFFORT, TIAGO_SPEED, 80.0, 0.5).loop_gain == 0.5


def test_set_servo_damping_changes_the_velocity_actuators_force():
    model = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody><body><joint name="j" type="hinge" axis="0 0 1"/>
        <geom type="box" size="0.1 0.1 0.1"/></body></worldbody>
        <actuator><velocity name="a" joint="j" kv="80"/></actuator></mujoco>"""
    )
    data = mujoco.MjData(model)
    set_servo_damping(model, np.array([0]), np.array([1.5]))
    data.ctrl[0] = 2.0
    mujoco.mj_forward(model, data)
    assert data.actuator_force[0] == pytest.approx(1.5 * 2.0)
