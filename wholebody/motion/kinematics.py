"""Whole-body kinematics of a wheeled mobile manipulator: FK and the combined Jacobian (paper eq. 11-21).

Reduced coordinates ``x = [x, y, theta, q_arm...]`` (base pose on the floor + arm
joints). Velocity input ``u = [q_arm_dot..., base input...]`` where the base input is
the wheel rates (paper eq. 20 ordering: the arm joints then the wheels) or, for a
holonomic base with ``base_input="twist"``, the body twist (vx, vy, wz). Any number of arm joints;
every other joint (torso, head, fingers, casters) is held at its locked value from the robot's profile.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from robots.checks import reference_configuration, wheel_geometry
from robots.loading import LoadedRobot
from robots.profiles import RobotProfile, mobile_manipulators
from wholebody.errors import WholeBodyError
from wholebody.motion.bases import DifferentialDrive, MobileBase, Omnidirectional
from wholebody.motion.kernels import integrate_state, write_configuration

#: The base part of the input vector u: wheel rates, or the body twist (vx, vy, wz) of a holonomic base.
BaseInput = Literal["wheels", "twist"]


class WholeBody:
    """A mobile manipulator seen as [planar base pose, arm joints] driven by [arm rates, base input].

    Args:
        robot: a `robots.load(...)` result (planar root joint `root_joint`).
        base: the base model mapping wheel rates to body twists.
        arm_joints: names of the arm joints, in the order of the reduced vectors.
        wheel_joints: names of the driven wheel joints, in the base's wheel order.
        ee_frame: role or frame name of the end effector.
        base_input: "wheels" (wheel rates) or "twist" (body twist; holonomic bases only).
        q_reference: Pinocchio configuration of the joints outside x (locked joints); None = the profile's
            locked values (`robots.checks.reference_configuration`), or neutral without a profile.
    """

    def __init__(
        self,
        robot: LoadedRobot,
        base: MobileBase,
        arm_joints: Sequence[str],
        wheel_joints: Sequence[str],
        ee_frame: str = "ee",
        base_input: BaseInput = "wheels",
        q_reference: np.ndarray | None = None,
    ) -> None:
        self.robot = robot
        self.model: pin.Model = robot.model
        self.data: pin.Data = robot.model.createData()
        self.base = base
        self.arm_joints = tuple(arm_joints)
        self.wheel_joints = tuple(wheel_joints)
        if base_input not in ("wheels", "twist"):
            raise WholeBodyError(f"base_input must be 'wheels' or 'twist', got {base_input!r}")
        if base_input == "twist" and not base.holonomic:
            raise WholeBodyError("base_input='twist' needs a holonomic base; a differential drive takes wheel rates")
        self.base_input = base_input
        if len(self.wheel_joints) != base.n_wheels:
            raise WholeBodyError(f"{len(self.wheel_joints)} wheel joints for a base with {base.n_wheels} wheels")
        self.ee_frame_id = robot.frame_id(ee_frame)
        root = self.model.getJointId("root_joint")
        if root >= self.model.njoints or self.model.joints[root].shortname() != "JointModelPlanar":
            raise WholeBodyError("the robot must have a planar root joint named 'root_joint'")
        self._root_v = self.model.joints[root].idx_v
        self._root_q = self.model.joints[root].idx_q
        self.arm_idx_q = np.array([self._joint(n).idx_q for n in self.arm_joints])
        self.arm_idx_v = np.array([self._joint(n).idx_v for n in self.arm_joints])
        self.wheel_idx_q = np.array([self._joint(n).idx_q for n in self.wheel_joints])
        self.wheel_idx_v = np.array([self._joint(n).idx_v for n in self.wheel_joints])
        self.n_arm = len(self.arm_joints)
        self.n_base_input = 3 if base_input == "twist" else base.n_wheels
        self.n_u = self.n_arm + self.n_base_input
        self.arm_lower = self.model.lowerPositionLimit[self.arm_idx_q].copy()
        self.arm_upper = self.model.upperPositionLimit[self.arm_idx_q].copy()
        self.arm_velocity_limit = self.model.velocityLimit[self.arm_idx_v].copy()
        self.wheel_velocity_limit = self.model.velocityLimit[self.wheel_idx_v].copy()
        if q_reference is None:
            prof = robot.profile
            q_reference = pin.neutral(self.model) if prof is None else reference_configuration(prof, self.model)
        q_reference = np.asarray(q_reference, dtype=float)
        if q_reference.shape != (self.model.nq,):
            raise WholeBodyError(f"q_reference must have shape ({self.model.nq},), got {q_reference.shape}")
        self._q_neutral = q_reference.copy()
        self._wheel_map = self.wheel_map()
        #: 3 x n_base_input map from the base input to the base body twist (vx, vy, wz)
        self.twist_map = self._wheel_map
        self._q_work = self._q_neutral.copy()  # configuration buffer of ee_and_jacobian
        self._x_shape = (3 + self.n_arm,)
        self._input_map = self._velocity_from_input()

    def _velocity_from_input(self) -> np.ndarray:
        """Return the nv x n_u map from the input u to the Pinocchio velocity (planar root <- base input)."""
        S = np.zeros((self.model.nv, self.n_u))
        S[self.arm_idx_v, np.arange(self.n_arm)] = 1.0
        S[self._root_v : self._root_v + 3, self.n_arm :] = self._wheel_map
        return S

    @property
    def input_map(self) -> np.ndarray:
        """Return the nv x n_u map S from the input u to the Pinocchio velocity (arm joints, planar root)."""
        return self._input_map

    def _joint(self, name: str) -> pin.JointModel:
        if not self.model.existJointName(name):
            raise WholeBodyError(f"robot {self.robot.name!r} has no joint {name!r}")
        return self.model.joints[self.model.getJointId(name)]

    # ------------------------------------------------------------------ configuration
    def as_state(self, x: npt.ArrayLike) -> np.ndarray:
        """Return x as a float array of shape (3 + n_arm,), or raise `WholeBodyError`."""
        xa = np.asarray(x, dtype=float)
        if xa.shape != self._x_shape:
            raise WholeBodyError(f"state x must have shape {self._x_shape} (x, y, theta, arm joints), got {xa.shape}")
        return xa

    def to_pinocchio_q(self, x: npt.ArrayLike, wheel_angles: npt.ArrayLike | None = None) -> np.ndarray:
        """Return the Pinocchio configuration of reduced coordinates x (other joints neutral)."""
        xa = self.as_state(x)
        q = self._q_neutral.copy()
        write_configuration(q, xa, self._root_q, self.arm_idx_q)
        if wheel_angles is not None:
            a = np.asarray(wheel_angles, dtype=float)
            q[self.wheel_idx_q] = np.cos(a)
            q[self.wheel_idx_q + 1] = np.sin(a)
        return q

    def wheel_map(self) -> np.ndarray:
        """Return the 3 x n_base_input map from the base input to the body twist (vx, vy, wz)."""
        return np.eye(3) if self.base_input == "twist" else self.base.wheel_to_body_twist()

    def body_twist(self, u: npt.ArrayLike) -> np.ndarray:
        """Return the base body twist (vx, vy, wz) of an input u (vy = 0 exactly for a differential drive)."""
        return self._wheel_map @ np.asarray(u, dtype=float)[self.n_arm :]

    @property
    def arm_effort_limit(self) -> np.ndarray:
        """Return the arm joints' torque (force) limits from the URDF (N m or N)."""
        return self.model.effortLimit[self.arm_idx_v].copy()

    def wheel_rates(self, u: npt.ArrayLike) -> np.ndarray:
        """Return the wheel rates (rad/s) implied by an input vector u."""
        ub = np.asarray(u, dtype=float)[self.n_arm :]
        return self.base.body_twist_to_wheels(ub) if self.base_input == "twist" else ub

    def integrate(self, x: npt.ArrayLike, u: npt.ArrayLike, dt: float) -> np.ndarray:
        """Return x after applying input u for dt: arm joints linearly, the base by exact odometry (eq. 4-10)."""
        ua = np.asarray(u, dtype=float)
        if ua.shape != (self.n_u,):
            raise WholeBodyError(f"input u must have shape ({self.n_u},) (arm rates, base input), got {ua.shape}")
        return integrate_state(self.as_state(x), ua, float(dt), self._wheel_map, self.n_arm)

    # ------------------------------------------------------------------ kinematics
    def frame_placement(self, x: npt.ArrayLike, frame: str | int | None = None) -> pin.SE3:
        """Return the world placement of a frame (default: the end effector), paper eq. (13)."""
        fid = self.ee_frame_id if frame is None else (frame if isinstance(frame, int) else self.robot.frame_id(frame))
        q = self.to_pinocchio_q(x)
        pin.framesForwardKinematics(self.model, self.data, q)
        return pin.SE3(self.data.oMf[fid])

    def ee_placement(self, x: npt.ArrayLike) -> pin.SE3:
        """Return the world placement of the end effector, paper eq. (13)."""
        return self.frame_placement(x)

    def ee_and_jacobian(self, x: npt.ArrayLike) -> tuple[pin.SE3, np.ndarray]:
        """Return (end-effector placement, combined Jacobian) with one kinematics pass.

        Writes x into a reused configuration buffer (wheel angles stay neutral) and makes one
        `computeFrameJacobian` call (forward kinematics of the EE's support and its Jacobian); the combined
        Jacobian is that Jacobian times the input -> velocity map (arm columns selected, the planar joint's
        body twist chained with the base's wheel map, eq. 19-20).
        """
        q = self._q_work
        write_configuration(q, self.as_state(x), self._root_q, self.arm_idx_q)
        J = pin.computeFrameJacobian(self.model, self.data, q, self.ee_frame_id, pin.LOCAL_WORLD_ALIGNED)
        oMf = pin.updateFramePlacement(self.model, self.data, self.ee_frame_id)
        return oMf.copy(), J.dot(self._input_map)

    def frame_and_jacobian(self, x: npt.ArrayLike, frame_id: int) -> tuple[pin.SE3, np.ndarray]:
        """Return (placement, 6 x n_u combined Jacobian) of any frame, e.g. a second hand (`ee_and_jacobian` alike)."""
        q = self._q_work
        write_configuration(q, self.as_state(x), self._root_q, self.arm_idx_q)
        J = pin.computeFrameJacobian(self.model, self.data, q, frame_id, pin.LOCAL_WORLD_ALIGNED)
        oMf = pin.updateFramePlacement(self.model, self.data, frame_id)
        return oMf.copy(), J.dot(self._input_map)

    def combined_jacobian(self, x: npt.ArrayLike) -> np.ndarray:
        """Return the 6 x n_u Jacobian u -> end-effector (v, omega), world-aligned at the EE (paper eq. 21)."""
        return self.ee_and_jacobian(x)[1]


def wholebody_for(
    robot: LoadedRobot, base_input: BaseInput | None = "wheels", arm: int | Sequence[int] = 0
) -> WholeBody:
    """Return the `WholeBody` of a loaded robot with its arm number `arm`, built from its profile.

    ``base_input``: "wheels" (wheel rates, the default), "twist" (holonomic bases), or None = the profile's
    (`RobotProfile.base_input`: a body twist for a holonomic base, wheel rates for a differential drive).
    ``arm``: one arm, or several (one base driving them all): their joints in that order in x and u, the
    end effector the first one's gripper frame (`frame_and_jacobian` gives the others').
    """
    prof = robot.profile
    if prof is None or not prof.is_mobile_manipulator:
        raise WholeBodyError(
            f"no whole-body model for robot {robot.name!r} (no arm on a wheeled base in its profile); "
            f"use {' or '.join(repr(n) for n in mobile_manipulators())} or a profile with [[arms]] and wheel_joints"
        )
    which = [arm] if isinstance(arm, int) else list(arm)
    if not which or any(not 0 <= i < len(prof.arms) for i in which) or len(set(which)) != len(which):
        raise WholeBodyError(f"robot {robot.name!r} has {len(prof.arms)} arm(s) in its profile; arm(s) {arm} asked")
    arms = [prof.arms[i] for i in which]
    return WholeBody(
        robot,
        base_for(robot, prof),
        [j for a in arms for j in a.joints],
        prof.wheel_joints,
        ee_frame=arms[0].gripper_frame,
        base_input=prof.base_input if base_input is None else base_input,
    )


def base_for(robot: LoadedRobot, prof: RobotProfile) -> MobileBase:
    """Return the base model of a profile: a differential drive or mecanum wheels, dimensions from the profile
    where it gives them, else read off the URDF (`robots.checks.wheel_geometry`)."""
    geo = wheel_geometry(prof, robot.model)
    if prof.base == "holonomic":
        return Omnidirectional(geo.radius, geo.positions)
    if geo.separation is None:  # set by wheel_geometry for every differential base
        raise WholeBodyError(f"robot {robot.name!r}: no wheel separation for a {prof.base!r} base")
    return DifferentialDrive(geo.separation, geo.radius)
