"""The arm's inertia fed forward under the hand's predicted acceleration (`arm_control.hand_inertia_torque`).

Physics against Pinocchio: the Ridgeback + iiwa model (planar root joint), its base accelerating, its hand
asked to follow a prescribed acceleration in free space (no cart). With the inertial torque on top of the bias
forces (``tau = b + hand_inertia_torque``, and no ``J^T w``: nothing to push) the arm's own forward dynamics make
the hand follow that acceleration, so the hand needs no wrench from outside (its F/T would read zero); the torque is
Pinocchio's RNEA at those accelerations. With the bias forces alone it does not follow.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from robots.loading import load
from wholebody.push.arm_control import hand_inertia_terms, hand_inertia_torque


@pytest.fixture(scope="module")
def iiwa():
    return load("ridgeback_iiwa")


def _arm(robot) -> np.ndarray:
    """Return the arm joints' velocity indices (base to tip)."""
    model = robot.model
    return np.array([model.joints[model.getJointId(n)].idx_v for n in robot.profile.arm_joints])


def _state(robot, seed: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Return a random (q, v) with the arm away from its singularities (the other joints at rest) and the hand frame."""
    model = robot.model
    rng = np.random.default_rng(seed)
    q = pin.neutral(model)
    q[:2] = rng.normal(size=2)
    q[2:4] = [np.cos(0.7), np.sin(0.7)]  # the planar root's yaw as (cos, sin)
    arm_q = np.array([model.joints[model.getJointId(n)].idx_q for n in robot.profile.arm_joints])
    q[arm_q] = rng.uniform(-0.5, 0.5, arm_q.size) + np.r_[0.0, 0.6, 0.0, -1.2, 0.0, 0.8, 0.0]
    v = np.zeros(model.nv)
    v[:3] = rng.normal(0.0, 0.5, 3)
    v[_arm(robot)] = rng.normal(0.0, 0.5, arm_q.size)
    return q, v, model.getFrameId(robot.frames["ee"])


def _hand_acceleration(robot, q: np.ndarray, v: np.ndarray, qdd: np.ndarray, frame: int) -> np.ndarray:
    """Return the hand frame's classical acceleration (linear, angular), world-aligned (Pinocchio)."""
    model, data = robot.model, robot.data
    pin.forwardKinematics(model, data, q, v, qdd)
    pin.updateFramePlacements(model, data)
    return pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED).vector.copy()


def _arm_response(robot, q, v, a_base, tau_arm) -> np.ndarray:
    """Return the joint accelerations [a_base, qdd_arm] of the arm under `tau_arm` with the base's acceleration
    prescribed (the arm's rows of the dynamics; no external force on the hand)."""
    model, data = robot.model, robot.data
    M = _inertia(robot, q)
    a = _arm(robot)
    b = pin.rnea(model, data, q, v, np.zeros(model.nv))
    qdd = np.zeros(model.nv)
    qdd[:3] = a_base
    qdd[a] = np.linalg.solve(M[np.ix_(a, a)], tau_arm - b[a] - M[a, :3] @ a_base)
    return qdd


def _inertia(robot, q: np.ndarray) -> np.ndarray:
    M = pin.crba(robot.model, robot.data, q)
    return np.triu(M) + np.triu(M, 1).T


def _parts(robot, q: np.ndarray, frame: int):
    """Return (M_aa, M_ab, J_a, J_b): the arm's rows of the inertia and the hand's Jacobian (world-aligned)."""
    M = _inertia(robot, q)
    pin.computeJointJacobians(robot.model, robot.data, q)
    J = pin.getFrameJacobian(robot.model, robot.data, frame, pin.LOCAL_WORLD_ALIGNED)
    a, base = _arm(robot), np.arange(3)
    return M[np.ix_(a, a)], M[np.ix_(a, base)], J[:, a], J[:, base]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_inertial_torque_makes_the_hand_follow_its_acceleration_with_no_wrench(iiwa, seed):
    model, data = iiwa.model, iiwa.data
    q, v, frame = _state(iiwa, seed)
    rng = np.random.default_rng(100 + seed)
    a_base = rng.normal(0.0, 0.5, 3)  # the planar root's acceleration (its own coordinates)
    a_hand = rng.normal(0.0, 0.5, 6)
    parts = _parts(iiwa, q, frame)
    jdot_qdot = _hand_acceleration(iiwa, q, v, np.zeros(model.nv), frame)
    tau_in = hand_inertia_torque(*parts, jdot_qdot, a_hand, a_base)
    arm = _arm(iiwa)
    b = pin.rnea(model, data, q, v, np.zeros(model.nv))[arm]
    qdd = _arm_response(iiwa, q, v, a_base, b + tau_in)
    np.testing.assert_allclose(_hand_acceleration(iiwa, q, v, qdd, frame), a_hand, atol=1e-5)  # the 1e-9 ridge
    np.testing.assert_allclose(pin.rnea(model, data, q, v, qdd)[arm], b + tau_in, atol=1e-8)
    # the bias forces alone: the hand does not follow (the push would have to make up the difference)
    qdd_b = _arm_response(iiwa, q, v, a_base, b)
    assert np.linalg.norm(_hand_acceleration(iiwa, q, v, qdd_b, frame) - a_hand) > 0.1
    # the split the law takes once per period: t + K a_base
    t, K = hand_inertia_terms(*parts, jdot_qdot, a_hand)
    np.testing.assert_allclose(t + K @ a_base, tau_in, atol=1e-9)


def test_the_inertial_torque_is_the_least_kinetic_energy_one(iiwa):
    """Of the joint accelerations that give the hand its acceleration, the torque's has no null-space motion:
    ``qdd_arm`` lies in the range of ``M^-1 J^T`` (a 7-joint arm: a 1-D null space it leaves alone)."""
    q, _, frame = _state(iiwa, 5)
    M_aa, M_ab, Ja, Jb = _parts(iiwa, q, frame)
    a_hand = np.array([0.4, -0.2, 0.1, 0.3, 0.0, -0.5])
    tau_in = hand_inertia_torque(M_aa, M_ab, Ja, Jb, np.zeros(6), a_hand, np.zeros(3))
    qdd_arm = np.linalg.solve(M_aa, tau_in)
    null = np.linalg.svd(Ja)[2][6:].T  # the arm's kinematic null space
    # the kinetic-energy metric: qdd_arm is M-orthogonal to every null-space motion
    np.testing.assert_allclose(null.T @ M_aa @ qdd_arm, 0.0, atol=1e-8)
    np.testing.assert_allclose(Ja @ qdd_arm, a_hand, atol=1e-5)
