"""Two robots side by side stand as far from the handle (arm mount to hand, in the plane) as one robot alone: their
arms are no more stretched than the one-arm push posture (two arms on MuJoCo lost the cart on Traj. 1 when they were)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wholebody.push import PushConfig
from wholebody.push.loop import build_controller


def _mount_to_hand(mm) -> float:
    wb = mm.wb
    data = wb.model.createData()
    pin.forwardKinematics(wb.model, data, wb.to_pinocchio_q(mm.x))
    pin.updateFramePlacements(wb.model, data)
    mount = data.oMi[wb.model.getJointId(wb.arm_joints[0])].translation
    hand = data.oMf[mm.ee_id].translation
    return float(np.linalg.norm((hand - mount)[:2]))


@pytest.mark.parametrize("plant", ["kinematic", "mujoco"])
def test_side_by_side_arms_reach_like_one(plant):
    contact = "fixed" if plant == "mujoco" else "optimal"
    one = build_controller(PushConfig(trajectory=1, n_arms=1, plant=plant, contact=contact)).controller.robots
    two = build_controller(PushConfig(trajectory=1, n_arms=2, plant=plant, contact=contact)).controller.robots
    assert len(two) == 2
    alone = _mount_to_hand(one[0])
    for mm in two:
        assert abs(mm.base_offset_b[1]) > 0.3  # the bases stand beside their contacts (at +-0.2 m)
        assert _mount_to_hand(mm) == pytest.approx(alone, abs=0.01)


def test_two_robots_with_a_fixed_base_place_hold_fixed_contacts_beyond_one_robots_reach():
    """One WMRA (its base at a fixed place, arm on its left) holds y in [-0.125, 0.25] m; two side by side stand
    behind their own contacts and hold the MuJoCo plant's fixed y = -0.2 / +0.2 m (the single robot's reach map
    refused the first before)."""
    from wholebody.push.robot import grasp_target

    cfg = PushConfig(trajectory=1, robot="wmra", n_arms=2, plant="mujoco", contact="fixed")
    ctrl = build_controller(cfg).controller
    assert np.allclose(ctrl.scheduler.y, [-0.2, 0.2])
    q0 = cfg.make_trajectory().sample(0.0)[0]
    for mm, y in zip(ctrl.robots, ctrl.scheduler.y):
        target, _ = grasp_target(q0, np.zeros(3), float(y), 0.0, mm.R_b_ee)
        assert np.linalg.norm(mm.wb.ee_placement(mm.x).translation - target.translation) < 1e-4
        assert abs(mm.base_offset_b[1] - y) < 0.5  # each base behind its own contact


@pytest.mark.parametrize("robot", ["ridgeback_iiwa", "wmra"])
def test_side_by_side_bases_stand_clear_and_no_farther_apart_than_needed(robot):
    """The bases' footprints keep `BASE_CLEARANCE` between them and stand no farther apart (the 0.6 m wide WMRA stood
    0.9 m apart, as the 0.79 m Ridgebacks, its arm then at a joint limit in Traj. 2's first turn); each arm's mount
    is as far from its hand as when the robot pushes alone, the mount's place on the base counted (the WMRA's arm
    sits 0.23 m left of its axle's centre)."""
    import robots
    from wholebody.push.robot import BASE_CLEARANCE, base_footprint_width

    one = build_controller(PushConfig(trajectory=1, n_arms=1, plant="mujoco", contact="fixed", robot=robot))
    two = build_controller(PushConfig(trajectory=1, n_arms=2, plant="mujoco", contact="fixed", robot=robot))
    mms = two.controller.robots
    gap = mms[1].base_offset_b[1] - mms[0].base_offset_b[1]
    assert gap == pytest.approx(base_footprint_width(robots.load(robot)) + BASE_CLEARANCE, abs=1e-9)
    alone = _mount_to_hand(one.controller.robots[0])
    for mm in mms:
        assert _mount_to_hand(mm) == pytest.approx(alone, abs=0.01)
