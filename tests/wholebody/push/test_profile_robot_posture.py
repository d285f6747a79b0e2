"""A robot known only by its profile: computed push settings, grasp, arm torques as constraints on the hand wrench."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import robots
from robots.profiles import profile
from tests.robots.profile_files import tiago_profile
from wholebody.push.robot import (
    R_B_EE0,
    grasp_rotation,
    grasp_target,
    handle_point,
    make_robots,
    push_grasp_rotation,
    push_profile,
    push_reach_map,
)


@pytest.fixture(scope="module")
def tiago(tmp_path_factory):
    return robots.load(tiago_profile(tmp_path_factory.mktemp("tiago")))


def test_tuned_builtin_profiles_are_used_as_they_are():
    for name in ("ridgeback_iiwa", "wmra"):
        raw, full = profile(name), push_profile(name)
        assert full.push_arm_seed == raw.push_arm_seed and full.push_base_x == raw.push_base_x
        assert full.grasp_pitch == raw.grasp_pitch and full.push_base_y == raw.push_base_y
        assert full.push_contact_y == raw.push_contact_y and full.arms[0].tool_axis == "z"
    assert push_profile("ridgeback_iiwa").base_twist_limit == (1.1, 1.1, 2.0)
    # the WMRA's twist limits from its URDF's wheel speed limit: r w and 2 r w / track
    v = robots.wmra.WMRA_WHEEL_RADIUS * robots.wmra.WMRA_WHEEL_VELOCITY
    assert push_profile("wmra").base_twist_limit == pytest.approx((v, 0.0, 2 * v / robots.wmra.WMRA_TRACK), abs=1e-12)


@pytest.mark.parametrize("axis, column", [("z", 2), ("x", 0), ("-x", 0), ("y", 1), ("-y", 1), ("-z", 2)])
def test_grasp_rotation_points_the_named_tool_axis_forward_and_down(axis, column):
    pitch = 0.7
    R = grasp_rotation(pitch, 0.4, axis)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    sign = -1.0 if axis.startswith("-") else 1.0
    tool = sign * R[:, column]  # the gripper's tool axis in {b}
    np.testing.assert_allclose(tool, [np.cos(pitch), 0.0, -np.sin(pitch)], atol=1e-12)
    np.testing.assert_allclose(grasp_rotation(pitch), grasp_rotation(pitch, 0.0, "z"), atol=0)
    assert np.array_equal(grasp_rotation(0.0), R_B_EE0)


def test_tiago_push_posture_is_computed_and_holds_the_handle(tiago):
    prof = push_profile(tiago)
    assert not prof.tuned and prof.arms[0].tool_axis == "x"  # TIAGo's arm_tool_link points along x
    assert prof.push_base_y is not None and -1.4 <= prof.push_base_x <= -0.45  # a differential base: fixed place
    mm = make_robots(tiago, np.array([0.4, -0.3, 0.5]), [0.0])[0]
    wb = mm.wb
    # the hand is on the handle point with the grasp orientation (independent: Pinocchio FK of the state)
    target, _ = grasp_target(np.array([0.4, -0.3, 0.5]), np.zeros(3), 0.0, 0.0, push_grasp_rotation(prof))
    q = wb.to_pinocchio_q(mm.x)
    pin.framesForwardKinematics(tiago.model, tiago.data, q)
    oMh = tiago.data.oMf[tiago.frame_id("arm_tool_link")]
    assert np.linalg.norm(pin.log6(oMh.actInv(target)).vector) < 1e-6
    qa = mm.x[3:]
    assert np.all(qa > wb.arm_lower + 0.1) and np.all(qa < wb.arm_upper - 0.1)
    # the base stands behind the handle, facing the cart's heading
    rel = pin.SE3(pin.utils.rpyToMatrix(0, 0, 0.5), np.array([0.4, -0.3, 0.0])).actInv(np.r_[mm.x[:2], 0.0])
    assert rel[0] < handle_point(0.0)[0] - 0.4 and mm.x[2] == pytest.approx(0.5)
    # a fixed base holds a stretch of the handle with margin (the reach map the scheduler uses)
    reach = push_reach_map(tiago)
    ok = reach.y[reach.reachable]
    assert ok.size and ok.max() - ok.min() >= 0.1 and reach.is_reachable(prof.push_contact_y)


def test_torque_constraint_is_gravity_plus_jacobian_transpose_of_the_hand_wrench(tiago):
    q_cart = np.array([0.4, -0.3, 0.5])
    mm = make_robots(tiago, q_cart, [0.0])[0]
    tc = mm.torque_constraint(q_cart)
    q = mm.wb.to_pinocchio_q(mm.x)
    g = pin.computeGeneralizedGravity(tiago.model, tiago.model.createData(), q)[mm.wb.arm_idx_v]
    np.testing.assert_allclose(tc.bias, g, atol=1e-9)  # at rest: gravity
    np.testing.assert_allclose(tc.limit, [39.0, 39.0, 17.86, 17.86, 3.0, 6.6, 6.6])  # TIAGo's URDF efforts
    assert tc.joints == tuple(f"arm_{i}_joint" for i in range(1, 8))
    # virtual work: a wrench w_a (in {a}, like {b}) at the hand does w . dX/dq_j on joint j
    w_a = np.array([20.0, -5.0, 3.0, 0.4, -0.2, 1.0])
    c, s = np.cos(q_cart[2]), np.sin(q_cart[2])
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    w = np.r_[R @ w_a[:3], R @ w_a[3:]]
    M0 = mm.wb.ee_placement(mm.x)
    eps = 1e-6
    for j in range(mm.wb.n_arm):
        x = mm.x.copy()
        x[3 + j] += eps
        M = mm.wb.ee_placement(x)
        work = w[:3] @ (M.translation - M0.translation) / eps + w[3:] @ pin.log3(M.rotation @ M0.rotation.T) / eps
        assert tc.torques(w_a)[j] - g[j] == pytest.approx(work, abs=1e-4)
    # and the loop's torque model (rnea + J^T w) agrees at rest
    tau, _, _, _ = mm.torques(np.zeros(mm.wb.n_u), np.zeros(mm.wb.n_u), 0.01, w)
    np.testing.assert_allclose(tau, tc.torques(w_a), atol=1e-9)


def test_two_robots_from_one_profile_hold_their_own_contacts(tiago):
    mms = make_robots(tiago, np.zeros(3), [-0.2, 0.2])
    assert len(mms) == 2
    for mm, y in zip(mms, (-0.2, 0.2)):
        target, _ = grasp_target(np.zeros(3), np.zeros(3), y, 0.0, mm.R_b_ee)
        assert np.linalg.norm(mm.wb.ee_placement(mm.x).translation - target.translation) < 1e-6
    # the bases stand clear of each other: TIAGo's round base (its mesh 0.50 m wide) plus 0.1 m of clearance
    assert mms[1].x[1] - mms[0].x[1] == pytest.approx(0.4995 + 0.1, abs=1e-3)


def test_a_gripper_frame_at_the_last_joints_origin_reads_its_axis_against_the_joint_before(tmp_path):
    """The WMRA's ee sits at arm_joint7's origin; turned -90 deg about y its x axis points from the wrist to the
    fingertips: read against arm_joint6 the tool axis is "x" (it was "z", the fallback, for any such frame)."""
    from tests.robots.profile_files import write_profile
    from tests.robots.test_profiles import WMRA, wmra_text
    from wholebody.motion.kinematics import wholebody_for
    from wholebody.push.robot import tool_axis

    text = WMRA.read_text()
    old = '<child link="ee"/>\n    <origin xyz="0 0 0" rpy="0 0 0"/>'
    assert old in text
    for rpy, axis in (("0 -1.570796326795 0", "x"), ("0 0 0", "z")):
        (tmp_path / "wmra.urdf").write_text(
            text.replace(old, f'<child link="ee"/>\n    <origin xyz="0 0 0" rpy="{rpy}"/>')
        )
        loaded = robots.load(write_profile(tmp_path, wmra_text()))
        assert tool_axis(wholebody_for(loaded, loaded.profile.base_input, arm=0)) == axis
