"""Cross-check of the generic whole-body code on a robot that is not ours: TIAGo from example-robot-data.

TIAGo (PAL Robotics) is a differential-drive mobile manipulator with a prismatic torso and a
7-DoF arm. Its URDF is read from the files the `example-robot-data` distribution installs
(no copy in this repository), loaded by Pinocchio with a planar root joint, and wrapped in
`wholebody.motion.kinematics.WholeBody` with a `DifferentialDrive` whose track and wheel radius are
read off the model. Checked against computations that do not use our Jacobian code:

- the combined Jacobian (torso + arm + wheel columns) against central finite differences of
  the end-effector placement, stepping the configuration with Pinocchio's own `integrate`
  (exact SE(2) exponential of the planar root joint);
- the wheel map against rolling without slip: with the joint velocity our base model implies
  for given wheel rates, the floor contact point of each wheel, computed by Pinocchio from the
  URDF's wheel joints, has zero velocity.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from robots.loading import LoadedRobot
from tests.optional import missing
from wholebody.motion.bases import DifferentialDrive
from wholebody.motion.kinematics import WholeBody

URDF = "tiago_no_hand.urdf"
ARM_JOINTS = ("torso_lift_joint",) + tuple(f"arm_{i}_joint" for i in range(1, 8))
WHEEL_JOINTS = ("wheel_left_joint", "wheel_right_joint")
EE_FRAME = "arm_tool_link"


def tiago_urdf() -> Path:
    """Return the path of TIAGo's URDF among the installed files of example-robot-data."""
    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError:
        missing("example-robot-data", "pip install -e '.[dev]'")
    matches = [f for f in dist.files or () if f.name == URDF and "tiago_description" in str(f)]
    assert matches, f"example-robot-data {dist.version} installs no tiago_description/.../{URDF}"
    path = Path(dist.locate_file(matches[0]))
    assert path.is_file(), path
    return path


@pytest.fixture(scope="module")
def tiago() -> WholeBody:
    path = tiago_urdf()
    model = pin.buildModelFromUrdf(str(path), pin.JointModelPlanar())
    geometry = pin.GeometryModel()  # kinematics only: no meshes needed
    robot = LoadedRobot(
        name="tiago",
        urdf=path,
        model=model,
        data=model.createData(),
        visual_model=geometry,
        collision_model=geometry,
        visual_data=pin.GeometryData(geometry),
        collision_data=pin.GeometryData(geometry),
        frames={"ee": EE_FRAME, "base": "base_footprint"},
    )
    left, right = (model.jointPlacements[model.getJointId(j)].translation for j in WHEEL_JOINTS)
    track = float(np.linalg.norm(left - right))
    wheel_radius = float(left[2])  # axle height above base_footprint, which lies on the floor
    assert 0.3 < track < 0.5 and 0.05 < wheel_radius < 0.15, (track, wheel_radius)
    return WholeBody(robot, DifferentialDrive(track, wheel_radius), ARM_JOINTS, WHEEL_JOINTS)


def random_states(wb: WholeBody, n: int, seed: int) -> list[np.ndarray]:
    """Return n reduced states [x, y, theta, torso, arm...] inside the joint limits."""
    rng = np.random.default_rng(seed)
    lo, hi = wb.arm_lower, wb.arm_upper
    margin = 0.1 * (hi - lo)
    return [
        np.concatenate([rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi, 1), rng.uniform(lo + margin, hi - margin)])
        for _ in range(n)
    ]


def pinocchio_velocity(wb: WholeBody, u: np.ndarray) -> np.ndarray:
    """Return the full Pinocchio joint velocity of input u: planar twist, torso/arm rates, wheel rates."""
    v = np.zeros(wb.model.nv)
    v[wb.arm_idx_v] = u[: wb.n_arm]
    v[wb._root_v : wb._root_v + 3] = wb.wheel_map() @ u[wb.n_arm :]
    v[wb.wheel_idx_v] = wb.wheel_rates(u)
    return v


def test_shapes_and_limits_come_from_the_urdf(tiago):
    assert tiago.n_arm == 8 and tiago.n_u == 10
    assert tiago.arm_lower[0] == pytest.approx(0.0) and tiago.arm_upper[0] == pytest.approx(0.35)
    assert np.all(tiago.arm_velocity_limit > 0) and np.all(tiago.wheel_velocity_limit > 0)


def test_combined_jacobian_matches_finite_differences_of_pinocchio_kinematics(tiago):
    h = 1e-6
    for x in random_states(tiago, 6, seed=3):
        J = tiago.combined_jacobian(x)
        q0 = tiago.to_pinocchio_q(x)
        M0 = tiago.ee_placement(x)
        fd = np.empty_like(J)
        for k in range(tiago.n_u):
            u = np.zeros(tiago.n_u)
            u[k] = 1.0
            v = pinocchio_velocity(tiago, u)
            placements = []
            for step in (h, -h):
                q = pin.integrate(tiago.model, q0, step * v)
                pin.framesForwardKinematics(tiago.model, tiago.data, q)
                placements.append(pin.SE3(tiago.data.oMf[tiago.ee_frame_id]))
            plus, minus = placements
            fd[:3, k] = (plus.translation - minus.translation) / (2 * h)
            fd[3:, k] = pin.log3(plus.rotation @ minus.rotation.T) / (2 * h)
        assert np.abs(J - fd).max() < 1e-6, np.abs(J - fd).max()
        # and the world-aligned frame: a pure base turn moves the EE like a point on the base
        turn = J[:, tiago.n_arm :] @ np.array([-1.0, 1.0])
        p = M0.translation - tiago.frame_placement(x, "base_footprint").translation
        assert np.allclose(turn[:3], np.cross(turn[3:], p), atol=1e-9)


def test_wheel_map_rolls_without_slip_on_the_urdf_wheels(tiago):
    model, data = tiago.model, tiago.data
    r = tiago.base.wheel_radius
    rng = np.random.default_rng(5)
    for x in random_states(tiago, 4, seed=7):
        u = np.concatenate([np.zeros(tiago.n_arm), rng.uniform(-3, 3, 2)])
        q = tiago.to_pinocchio_q(x)
        v = pinocchio_velocity(tiago, u)
        pin.forwardKinematics(model, data, q, v)
        twist = tiago.wheel_map() @ u[tiago.n_arm :]
        assert abs(twist[0]) > 1e-3 or abs(twist[2]) > 1e-3
        for name in tiago.wheel_joints:
            jid = model.getJointId(name)
            centre = data.oMi[jid].translation
            assert centre[2] == pytest.approx(r, abs=1e-9)
            vel = pin.getVelocity(model, data, jid, pin.LOCAL_WORLD_ALIGNED)  # at the wheel centre
            contact_velocity = vel.linear + np.cross(vel.angular, np.array([0.0, 0.0, -r]))
            assert np.abs(contact_velocity).max() < 1e-9, (name, contact_velocity)


def test_a_profile_builds_the_same_whole_body_model(tiago, tmp_path):
    """TIAGo described by a profile file (torso in the arm) = the model built by hand above: same joints,
    base, and combined Jacobian at random states (the profile path adds nothing and drops nothing)."""
    import robots
    from tests.robots.profile_files import tiago_profile
    from wholebody.motion.kinematics import wholebody_for

    wb = wholebody_for(robots.load(tiago_profile(tmp_path, arm=list(ARM_JOINTS))))
    assert wb.arm_joints == tiago.arm_joints and wb.wheel_joints == tiago.wheel_joints
    assert wb.base.track == pytest.approx(tiago.base.track) and wb.base.wheel_radius == pytest.approx(
        tiago.base.wheel_radius
    )
    for x in random_states(tiago, 5, seed=11):
        np.testing.assert_allclose(wb.combined_jacobian(x), tiago.combined_jacobian(x), atol=1e-12)
        np.testing.assert_allclose(wb.ee_placement(x).homogeneous, tiago.ee_placement(x).homogeneous, atol=1e-12)
