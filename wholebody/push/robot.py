"""One mobile manipulator holding the handle: grasp geometry, whole-body QP tracker, arm torques, F/T sensing."""

from __future__ import annotations

import math
from dataclasses import replace
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

import robots
from robots.profiles import RobotProfile, profile
from cart.simulate import MeasurementNoise
from wholebody.contacts.handle import HandleSegment
from wholebody.errors import WholeBodyError
from wholebody.motion.control import ControllerConfig, ResolvedRateController, StepResult
from wholebody.motion.kinematics import WholeBody, wholebody_for
from wholebody.push.config import BodyTracker

#: Grasp orientation in {b} at pitch 0: tool axis (ee z) along +x_b, fingers (ee x) along z_b, bar along ee y.
R_B_EE0 = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
#: Default grasp pitch (rad, about y_b): the tool points forward and 46 deg down onto the bar.
GRASP_PITCH = 0.8
#: Base origin relative to its contact point, in {b} (x behind the handle), and base yaw relative to the cart.
BASE_OFFSET_X = -0.65
#: Lateral offset (m) of each base beyond its contact when two robots push side by side (bases are 0.79 m wide).
TWO_ARM_BASE_SPREAD = 0.25
#: Ridgeback limits (robots/ridgeback_iiwa.py): |vx|, |vy| <= 1.1 m/s, |wz| <= 2 rad/s.
BASE_TWIST_LIMIT = np.array([1.1, 1.1, 2.0])


def grasp_rotation(pitch: float = GRASP_PITCH) -> np.ndarray:
    """Return R_b_ee of the grasp: R_y(pitch) @ R_B_EE0 (the bar stays along the ee y axis)."""
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ R_B_EE0


def cart_se3(q_cart: Sequence[float]) -> pin.SE3:
    """Return T_s_b: the cart frame {b} in the world ({b} sits at wheel-axle height)."""
    from robots.shopping_cart import CART_WHEEL_RADIUS

    c, s = math.cos(q_cart[2]), math.sin(q_cart[2])
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return pin.SE3(R, np.array([q_cart[0], q_cart[1], CART_WHEEL_RADIUS]))


def handle_point(y: float) -> np.ndarray:
    """Return the handle point with lateral coordinate y, in {b}."""
    h = HandleSegment.default()
    return np.array([h.start_b[0], y, h.start_b[2]])


def grasp_target(
    q_cart: np.ndarray, qd_cart: np.ndarray, y: float, ydot: float, R_b_ee: np.ndarray
) -> tuple[pin.SE3, np.ndarray]:
    """Return (world pose of the grasp frame, its spatial velocity (v, w) world-aligned at the grasp point)."""
    T_sb = cart_se3(q_cart)
    p_b = handle_point(y)
    T = T_sb * pin.SE3(R_b_ee, p_b)
    r = T_sb.rotation @ p_b
    om = qd_cart[2]
    v = np.array([qd_cart[0] - om * r[1], qd_cart[1] + om * r[0], 0.0]) + T_sb.rotation @ np.array([0.0, ydot, 0.0])
    return T, np.concatenate([v, [0.0, 0.0, om]])


def base_target(q_cart: np.ndarray, qd_cart: np.ndarray, offset_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (planar pose, world rates) of a base rigidly offset by offset_b = (x, y) in {b}, same heading."""
    c, s = math.cos(q_cart[2]), math.sin(q_cart[2])
    px, py = c * offset_b[0] - s * offset_b[1], s * offset_b[0] + c * offset_b[1]
    om = qd_cart[2]
    pose = np.array([q_cart[0] + px, q_cart[1] + py, q_cart[2]])
    return pose, np.array([qd_cart[0] - om * py, qd_cart[1] + om * px, om])


#: Whole-body QP settings of the push (task weight 1; the posture and base pulls are 1e-4 and 1e-3 of it).
PUSH_CONTROLLER = ControllerConfig(
    gain=20.0,
    damping=1e-7,
    secondary="posture",
    secondary_weight=1e-4,
    posture_gain=1.0,
    max_linear_speed=3.0,
    max_angular_speed=3.0,
    limit_margin=0.05,
    solver="daqp",
    fallback_solver="proxqp",
    base_weight=1e-3,
    base_gain=2.0,
)


class WholeBodyQPTracker:
    """`BodyTracker` of the project's whole-body QP (`wholebody.motion.control.ResolvedRateController`).

    The grasp frame follows the handle (feed-forward + `gain` feedback), the arm is pulled to its
    grasp posture, and the base to its nominal place behind its contact point (the controller's
    base regularisation). Bounds: joint positions/rates, and the Ridgeback's wheel speeds (which
    imply its twist limits 1.1 m/s, 1.1 m/s, 2 rad/s).
    """

    def __init__(self, wb: WholeBody, q_nominal: np.ndarray, config: ControllerConfig | None = None) -> None:
        if config is None:  # the robot's own base tracker and wheel limits (robots.profiles)
            prof = profile(wb.robot.name)
            config = replace(
                PUSH_CONTROLLER,
                base_lookahead=prof.base_lookahead,
                wheel_acceleration_limit=prof.wheel_acceleration_limit,
            )
        self.controller = ResolvedRateController(wb, config, posture=q_nominal)
        self.last: StepResult | None = None

    def step(
        self,
        x: np.ndarray,
        target: pin.SE3,
        target_velocity: np.ndarray,
        base_target: np.ndarray,
        base_velocity: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """Return u = [arm rates (7), base body twist (3)] for one period."""
        res = self.controller.step(
            x, target, target_velocity, dt, base_target=base_target, base_target_velocity=base_velocity
        )
        if not res.solver_ok:
            raise WholeBodyError("the whole-body velocity QP has no solution")
        self.last = res
        return res.u


def solve_grasp_ik(wb: WholeBody, base_pose: np.ndarray, target: pin.SE3, seed: Sequence[float]) -> np.ndarray:
    """Return arm joints placing the ee at target with the base at base_pose (bounded least squares)."""
    from scipy.optimize import least_squares

    x = np.r_[base_pose, np.zeros(wb.n_arm)]

    def residual(qa: np.ndarray) -> np.ndarray:
        x[3:] = qa
        return pin.log6(wb.ee_placement(x).actInv(target)).vector

    lo, hi = wb.arm_lower + 0.02, wb.arm_upper - 0.02
    sol = least_squares(residual, np.clip(seed, lo, hi), bounds=(lo, hi), xtol=1e-12, ftol=1e-12)
    if np.linalg.norm(sol.fun) > 1e-5:
        raise WholeBodyError(
            f"the arm cannot reach the handle from base pose {np.round(base_pose, 3)} "
            f"(residual {np.linalg.norm(sol.fun):.3g})"
        )
    return sol.x


def grasp_configuration(
    wb: WholeBody,
    prof: RobotProfile,
    q_cart: np.ndarray,
    contact_y: float,
    base_y: float,
    R_b_ee: np.ndarray,
    seed: Sequence[float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (base pose, arm joints) of the robot holding the handle at `contact_y` (m, in {b}).

    The base stands at ``(handle x + prof.push_base_x, base_y)`` in the cart frame {b}; the hand holds the bar
    with orientation ``R_b_ee``; the arm comes from `solve_grasp_ik` seeded with `seed` (default: the
    profile's push posture).
    """
    offset = np.array([handle_point(contact_y)[0] + prof.push_base_x, base_y])
    pose, _ = base_target(q_cart, np.zeros(3), offset)
    target, _ = grasp_target(q_cart, np.zeros(3), contact_y, 0.0, R_b_ee)
    qa = solve_grasp_ik(wb, pose, target, prof.push_arm_seed if seed is None else seed)
    return pose, qa


class MobileManipulator:
    """One mobile manipulator (a `robots.profiles` entry with an F/T sensor and a push posture) holding the handle.

    State ``x`` = [base pose, arm joints]; ``base_offset_b`` is where its base stays, in {b}
    (behind the handle, laterally at ``base_y``); the arm starts from the grasp IK.
    """

    def __init__(
        self,
        robot: robots.LoadedRobot,
        q_cart: np.ndarray,
        contact_y: float,
        base_y: float,
        R_b_ee: np.ndarray,
        tracker: BodyTracker | None = None,
        arm_seed: Sequence[float] | None = None,
    ) -> None:
        prof = profile(robot.name)
        if prof.ft_frame is None or prof.push_arm_seed is None:
            raise WholeBodyError(f"robot {robot.name!r} has no F/T sensor or push posture in robots.profiles")
        self.profile = prof
        # a holonomic base takes a body twist; a differential drive takes wheel rates, so that its lateral
        # velocity is zero by construction (combined Jacobian of paper 2, eq. 11-21)
        self.wb = wholebody_for(robot, base_input=prof.base_input)
        self.model = self.wb.model
        self.data = self.model.createData()
        self.R_b_ee = R_b_ee
        self.ee_id = self.wb.ee_frame_id
        self.ft_id = robot.frame_id(prof.ft_frame)
        self.base_offset_b = np.array([handle_point(contact_y)[0] + prof.push_base_x, base_y])
        pose, qa = grasp_configuration(self.wb, prof, q_cart, contact_y, base_y, R_b_ee, arm_seed)
        self.x = np.r_[pose, qa]
        self.tracker = tracker if tracker is not None else WholeBodyQPTracker(self.wb, qa)
        self.u = np.zeros(self.wb.n_u)
        self.effort_limit = self.model.effortLimit[self.wb.arm_idx_v].copy()

    def body_twist(self, u: np.ndarray) -> np.ndarray:
        """Return the base body twist (vx, vy, wz) of an input u (vy = 0 exactly for a differential drive)."""
        return self.wb._wheel_map @ np.asarray(u, dtype=float)[self.wb.n_arm :]

    def pin_state(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return Pinocchio (q, v) for the current x and input u (wheel joints left at rest)."""
        q = self.wb.to_pinocchio_q(self.x)
        v = np.zeros(self.model.nv)
        v[0:3] = self.body_twist(u)  # planar root joint: body twist
        v[self.wb.arm_idx_v] = u[: self.wb.n_arm]
        return q, v

    def torques(
        self, u: np.ndarray, u_prev: np.ndarray, dt: float, wrench_world: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, pin.SE3, pin.SE3]:
        """Return (arm torques, push part J^T w, ee placement, F/T sensor placement).

        tau = rnea(q, v, a)[arm] + J_arm^T w with w = [f; n] world-aligned at the ee (the wrench the hand
        applies to the cart; the cart pushes back with -w).
        """
        q, v = self.pin_state(u)
        _, v_prev = self.pin_state(u_prev)
        a = (v - v_prev) / dt
        tau = pin.rnea(self.model, self.data, q, v, a)[self.wb.arm_idx_v]
        J = pin.computeFrameJacobian(self.model, self.data, q, self.ee_id, pin.LOCAL_WORLD_ALIGNED)
        push = J[:, self.wb.arm_idx_v].T @ wrench_world
        pin.updateFramePlacements(self.model, self.data)
        return tau + push, push, pin.SE3(self.data.oMf[self.ee_id]), pin.SE3(self.data.oMf[self.ft_id])


def ft_measurement(
    wrench_world: np.ndarray, oMee: pin.SE3, oMft: pin.SE3, rng: np.random.Generator, noise: MeasurementNoise
) -> pin.Force:
    """Return the F/T sensor reading (sensor frame, at its origin) of a hand wrench, plus white noise."""
    at_origin = pin.SE3(np.eye(3), oMee.translation).act(pin.Force(wrench_world[:3], wrench_world[3:]))
    local = oMft.actInv(at_origin)
    return pin.Force(local.linear + rng.normal(0.0, noise.force, 3), local.angular + rng.normal(0.0, noise.torque, 3))


def ft_to_cart_gamma(reading: pin.Force, oMft: pin.SE3, q_cart_meas: np.ndarray) -> np.ndarray:
    """Return Gamma_MM (fx, fy in {s}, tau about the measured {b} origin) of one F/T reading (eq. 23–24)."""
    world = oMft.act(reading)
    at_b = pin.SE3(np.eye(3), np.array([q_cart_meas[0], q_cart_meas[1], 0.0])).actInv(world)
    return np.array([at_b.linear[0], at_b.linear[1], at_b.angular[2]])
