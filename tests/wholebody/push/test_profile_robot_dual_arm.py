"""One base driving two arms (a profile with two [[arms]]): TIAGo++ from example-robot-data holds the handle with
both hands (kinematic plant): one robot, two hands carrying the push, every joint torque within its URDF limit,
and the profile errors of a dual-arm robot."""

from __future__ import annotations

import numpy as np
import pytest

import robots
from cartpush.cli.app import main
from tests.robots.profile_files import need_example_robot_data, write_profile
from wholebody.push import PushConfig, run_push
from wholebody.push.robot import make_robots


@pytest.fixture(scope="module")
def tiago_dual() -> str:
    need_example_robot_data()
    return str(robots.example_profile("tiago_dual"))


def test_one_base_pushes_with_both_hands_within_every_torque_limit(tiago_dual):
    res = run_push(PushConfig(robot=tiago_dual, n_arms=2, trajectory=1, duration=8.0, contact="fixed"))
    m = res.metrics
    assert res.robot_x.shape[1:] == (1, 3 + 14)  # one base, both arms' joints in its state
    assert res.wrenches.shape[1] == 2 and res.arm_torque.shape[1:] == (2, 7)
    push = np.abs(res.wrenches[:, :, 0])  # each hand's push along the cart's x
    assert np.all(push.mean(axis=0) > 2.0)  # both hands carry the load ...
    assert push[:, 0].mean() == pytest.approx(push[:, 1].mean(), rel=0.5)  # ... in comparable shares
    assert np.all(np.abs(res.contact_y[0] - [-0.2, 0.2]) < 1e-9)
    assert m.tracking_rms_mm < 20.0 and m.grasp_error_max_m < 0.005
    ratio = np.abs(res.arm_torque) / res.effort_limit
    assert ratio.max() <= 1.0 and m.arm_torque_limit_ratio == pytest.approx(ratio.max())
    r = robots.load(tiago_dual)  # the limits are each arm's URDF efforts
    lim = [r.model.effortLimit[r.model.joints[r.model.getJointId(f"arm_right_{i}_joint")].idx_v] for i in range(1, 8)]
    np.testing.assert_allclose(res.effort_limit, lim)


def test_one_arm_of_a_dual_arm_profile_is_its_first_arm(tiago_dual):
    (mm,) = make_robots(tiago_dual, np.zeros(3), [0.0])
    assert mm.n_hands == 1 and mm.arms == (0,) and mm.joint_names[0] == "arm_left_1_joint"
    (both,) = make_robots(tiago_dual, np.zeros(3), [-0.2, 0.2])
    assert both.n_hands == 2 and sorted(both.arms) == [0, 1]
    # the arm mounted on the right takes the contact on the right (lower y)
    hands_y = [both.wb.frame_placement(both.x, f).translation[1] for f in both.hand_ids]
    assert hands_y[0] == pytest.approx(-0.2, abs=1e-4) and hands_y[1] == pytest.approx(0.2, abs=1e-4)


def test_a_joint_carrying_both_hands_is_a_profile_error(tiago_dual, tmp_path, capsys):
    text = open(tiago_dual).read()
    text = text.replace('joints = ["arm_left_1_joint"', 'joints = ["torso_lift_joint", "arm_left_1_joint"')
    text = text.replace("[locked]\ntorso_lift_joint = 0.2\n", "")
    bad = write_profile(tmp_path, text, "dual.toml")
    assert main(["push", "--robot", str(bad), "--arms", "2", "--duration", "8", "--json"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "arms[1].gripper_frame" in err and "'torso_lift_joint'" in err


def test_the_mujoco_plant_refuses_one_base_with_two_arms(tiago_dual, capsys):
    argv = ["push", "--robot", tiago_dual, "--arms", "2", "--plant", "mujoco", "--duration", "8", "--json"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "one arm per robot" in err and "--plant kinematic" in err


def test_arms_of_different_lengths_get_padded_rows():
    """Per-hand torque rows and limits stay one array when a robot's arms have different joint counts."""
    from types import SimpleNamespace

    from wholebody.push.controller import hand_rows
    from wholebody.push.loop import effort_limits

    mm = SimpleNamespace(effort_limit=np.array([40.0, 20.0, 3.0, 50.0, 10.0]), hand_cols=[slice(0, 3), slice(3, 5)])
    lim = effort_limits([mm])
    np.testing.assert_array_equal(lim, [[40.0, 20.0, 3.0], [50.0, 10.0, np.inf]])
    tau = hand_rows([np.array([4.0, -2.0, 0.3]), np.array([-5.0, 1.0])])
    np.testing.assert_array_equal(tau, [[4.0, -2.0, 0.3], [-5.0, 1.0, 0.0]])
    assert np.max(np.abs(tau) / lim) == pytest.approx(0.1)  # the padded joint never binds
    same = SimpleNamespace(effort_limit=np.array([40.0, 20.0, 40.0, 20.0]), hand_cols=[slice(0, 2), slice(2, 4)])
    np.testing.assert_array_equal(effort_limits([same]), [40.0, 20.0])  # alike arms: one row, as one arm's
