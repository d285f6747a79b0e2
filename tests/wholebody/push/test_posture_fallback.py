"""The push posture search (wholebody.push.posture): a base place farther back when the free search finds
none, and a reason when no place can do."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

import robots
from wholebody.errors import WholeBodyError
from wholebody.motion.kinematics import wholebody_for
from wholebody.push import posture
from wholebody.push.robot import filled_profile


@pytest.fixture(scope="module")
def wmra():
    loaded = robots.load("wmra")
    prof = replace(filled_profile(loaded), push_base_x=None, push_base_y=None)
    return prof, [wholebody_for(loaded, base_input=prof.base_input, arm=0)]


def test_when_the_free_search_finds_nothing_a_base_place_farther_back_is_tried(wmra, monkeypatch):
    prof, wbs = wmra
    found = posture._placement

    def only_far_back(wb, p, pitch, roll, axis):  # stands for an arm stretched at every place nearer than 0.9 m
        if p.push_base_x is None or p.push_base_x > -0.9:
            return None
        return found(wb, p, pitch, roll, axis)

    monkeypatch.setattr(posture, "_placement", only_far_back)
    out = posture.solve_push_placement(prof, wbs)
    assert out.push_base_x == -0.9  # the first fallback place that holds the handle
    monkeypatch.setattr(posture, "_placement", lambda *a: None)
    with pytest.raises(WholeBodyError, match="give \\[push\\] base_x"):
        posture.solve_push_placement(prof, wbs)


def test_a_handle_beyond_the_arms_length_is_named(wmra, monkeypatch):
    prof, wbs = wmra
    wb = wbs[0]
    data = wb.model.createData()
    q = wb.to_pinocchio_q(np.r_[np.zeros(3), 0.5 * (wb.arm_lower + wb.arm_upper)])
    pin.forwardKinematics(wb.model, data, q)
    shoulder = float(data.oMi[wb.model.getJointId(wb.arm_joints[0])].translation[2])
    from wholebody.push import robot as push_robot

    monkeypatch.setattr(push_robot, "handle_point", lambda y, geometry=None: np.array([-0.15, y, shoulder + 3.0]))
    monkeypatch.setattr(posture, "_placement", lambda *a: None)
    with pytest.raises(WholeBodyError, match="farther than the arm's length") as err:
        posture.solve_push_placement(prof, wbs)
    assert "mount the arm higher" in str(err.value)


@pytest.mark.parametrize("share, said", [(0.9, "go to the height, leaving at most"), (0.5, "give [push] base_x")])
def test_a_handle_at_the_edge_of_the_arms_reach_is_named(wmra, monkeypatch, share, said):
    """The height takes 90 % of the stretched arm (Unitree Z1 on a small base: 0.72 of 0.79 m): the reason is the
    reach, not the search's settings; at half the arm it is the settings."""
    prof, wbs = wmra
    wb = wbs[0]
    data = wb.model.createData()
    pin.forwardKinematics(wb.model, data, wb.to_pinocchio_q(np.r_[np.zeros(3), 0.5 * (wb.arm_lower + wb.arm_upper)]))
    pin.updateFramePlacements(wb.model, data)
    chain = [data.oMi[wb.model.getJointId(n)].translation for n in wb.arm_joints]
    chain.append(data.oMf[wb.ee_frame_id].translation)
    length = float(sum(np.linalg.norm(b - a) for a, b in zip(chain[:-1], chain[1:])))
    assert share * length > posture.REACH_SHARE * length or share < posture.REACH_SHARE
    from wholebody.push import robot as push_robot

    top = float(chain[0][2]) + share * length
    monkeypatch.setattr(push_robot, "handle_point", lambda y, geometry=None: np.array([-0.15, y, top]))
    monkeypatch.setattr(push_robot, "cart_se3", lambda q: pin.SE3.Identity())
    monkeypatch.setattr(posture, "_placement", lambda *a: None)
    with pytest.raises(WholeBodyError) as err:
        posture.solve_push_placement(prof, wbs)
    assert said in str(err.value), str(err.value)


def test_an_arm_too_weak_to_hold_itself_at_the_push_posture_is_refused(wmra, monkeypatch):
    prof, wbs = wmra
    found = posture._placement

    def weak(wb, p, pitch, roll, axis):  # stands for an arm whose efforts are a third of its weight's torque
        got = found(wb, p, pitch, roll, axis)
        return None if got is None else replace(got, gravity_ratio=3.24)

    monkeypatch.setattr(posture, "_placement", weak)
    with pytest.raises(WholeBodyError, match=r"own weight needs 3.24 x a joint's effort limit"):
        posture.solve_push_placement(prof, wbs)


def test_an_arm_of_fewer_than_six_joints_is_told_to_give_its_grasp(tmp_path, monkeypatch):
    import shutil

    shutil.copy(robots.DATA_DIR / "wmra.urdf", tmp_path / "wmra.urdf")
    joints = ", ".join(f'"arm_joint{i}"' for i in range(1, 6))
    (tmp_path / "five.toml").write_text(
        'name = "wmra_five"\nurdf = "wmra.urdf"\nbase = "differential"\n'
        'wheel_joints = ["wheel_left_joint", "wheel_right_joint"]\n'
        f'[[arms]]\njoints = [{joints}]\ngripper_frame = "ee"\n[locked]\narm_joint6 = 0.0\narm_joint7 = 0.0\n'
    )
    loaded = robots.load(tmp_path / "five.toml")
    prof = filled_profile(loaded)
    wbs = [wholebody_for(loaded, base_input=prof.base_input, arm=0)]
    monkeypatch.setattr(posture, "_placement", lambda *a: None)
    with pytest.raises(WholeBodyError, match="an arm of 5 joints holds the handle only in a few orientations"):
        posture.solve_push_placement(prof, wbs)


def test_a_wrist_joint_left_out_of_the_arm_is_named(tmp_path, monkeypatch):
    """The WMRA's arm listed without its last joint (arm_joint7, between arm_joint6 and the gripper frame): the
    search fails, and the reason is the joint held at 0, not the search's settings; locked, it is not named."""
    import shutil

    from tests.robots.profile_files import write_profile
    from tests.robots.test_profiles import WMRA, wmra_text

    shutil.copy(WMRA, tmp_path / "wmra.urdf")
    six = ", ".join(f'"arm_joint{i}"' for i in range(1, 7))
    loaded = robots.load(write_profile(tmp_path, wmra_text(arm=f'joints = [{six}]\ngripper_frame = "ee"\n')))
    prof = filled_profile(loaded)
    wbs = [wholebody_for(loaded, base_input=prof.base_input, arm=0)]
    monkeypatch.setattr(posture, "_placement", lambda *a: None)
    with pytest.raises(WholeBodyError, match="'arm_joint7' between the arm's last joint and its gripper frame"):
        posture.solve_push_placement(prof, wbs)
    assert posture._held_in_the_hand(wbs[0], ["arm_joint7"]) == []
