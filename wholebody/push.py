"""The closed loop: mobile manipulator(s) push the cart, the EKF closes the loop (cart paper §II–III).

One control period ``dt`` (100 Hz by default):

1. cart controller (``cart.control``, using the current parameter estimate)
   -> desired cart wrench Gamma_MM (paper eq. 26);
2. contact points on the handle (fixed, or re-planned every ``replan_period``
   from the estimated model and slid towards the plan at ``slide_speed``) and
   the wrench allocation QP (``wholebody.allocation``, paper eq. 25) ->
   end-effector wrenches;
3. arm joint torques ``tau = rnea(q, v, a) + J^T w`` (Pinocchio; the arm's own
   gravity and dynamics plus the push), checked against the iiwa's effortLimit;
4. each mobile manipulator's base + arm follow the grasp point on the moving
   handle with the project's whole-body QP (``wholebody.control``, through the
   :class:`WholeBodyQPTracker` adapter: joint, wheel-speed and twist limits,
   base pulled to its nominal place behind the handle);
5. cart dynamics: exact constrained model (``cart.simulate.rk4_step``) under
   the wrenches the hands apply;
6. measurements: cart pose and velocity as from motion capture, the F/T
   sensor's wrench (noise in the sensor frame) mapped to the cart through the
   robot's kinematics and the grasp map (paper eq. 23–24);
7. EKF (``cart.ekf.CartEKF``, paper eq. 8–20) -> state and parameter estimate.

The pieces meet through small interfaces (:class:`CartController`,
:class:`ParameterEstimator`, :class:`BodyTracker`) so any of them can be swapped.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Protocol, Sequence, Tuple

import numpy as np
import pinocchio as pin

import robots
from cart import model as cart_model
from cart.dynamics import inverse_dynamics
from cart.control import make_controller
from cart.ekf import CartEKF, EKFConfig
from cart.params import CartParams
from cart.simulate import MeasurementNoise, rk4_step
from cart.trajectories import UnicycleTrajectory, trajectory_1, trajectory_2
from wholebody.allocation import ArmLimits, WrenchAllocator
from wholebody.contact import HandleSegment
from wholebody.control import ControllerConfig, ResolvedRateController, StepResult
from wholebody.errors import WholeBodyError
from wholebody.kinematics import WholeBody, wholebody_for

#: Grasp orientation in {b} at pitch 0: tool axis (ee z) along +x_b, fingers (ee x) along z_b, bar along ee y.
R_B_EE0 = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
#: Default grasp pitch (rad, about y_b): the tool points forward and 46 deg down onto the bar.
GRASP_PITCH = 0.8
#: Base origin relative to its contact point, in {b} (x behind the handle), and base yaw relative to the cart.
BASE_OFFSET_X = -0.65
#: Arm posture of the iiwa holding the handle with the base at BASE_OFFSET_X (found by IK, joint-limit margin 1.1 rad).
ARM_SEED = (-1.70, -0.94, 0.28, 1.00, -0.43, -0.47, 0.25)
#: Lateral offset (m) of each base beyond its contact when two robots push side by side (bases are 0.79 m wide).
TWO_ARM_BASE_SPREAD = 0.25
#: Ridgeback limits (robots/ridgeback_iiwa.py): |vx|, |vy| <= 1.1 m/s, |wz| <= 2 rad/s.
BASE_TWIST_LIMIT = np.array([1.1, 1.1, 2.0])

#: The simulated cart of the default scenario (paper Table I test 5: 20 kg, CoM (0.3, 0.15)); I scaled
#: from the shopping cart of `robots` (1.7355 kg m^2 at 15 kg); viscous coefficient 4 N s/m.
TRUE_CART = CartParams(m=20.0, dx=0.3, dy=0.15, I=1.7355 * 20.0 / 15.0, sigma=4.0)


class CartController(Protocol):
    """Cart tracking law: desired Gamma_MM = (fx, fy in {s}, tau about the {b} origin)."""

    def gamma(self, t: float, q: np.ndarray, qd: np.ndarray, params: CartParams) -> np.ndarray:
        """Return the desired generalized force."""


class ParameterEstimator(Protocol):
    """State + parameter estimator fed with the applied wrench and the motion-capture measurement."""

    x: np.ndarray

    def step(self, gamma: Sequence[float], dt: float, z: Sequence[float]) -> float:
        """Predict over dt under gamma, then update with z = (x, y, theta, vx, vy, omega)."""

    def params(self) -> CartParams:
        """Return the current parameter estimate."""


class BodyTracker(Protocol):
    """Whole-body velocity controller of one mobile manipulator."""

    def step(self, x: np.ndarray, target: pin.SE3, target_velocity: np.ndarray, base_target: np.ndarray,
             base_velocity: np.ndarray, dt: float) -> np.ndarray:
        """Return the input u = [arm joint rates (7), base body twist (3)] for the next period."""


#: Sensor noise of the loop: motion capture (3 mm, 3 mrad, 1 cm/s, 0.01 rad/s) and the F/T sensor
#: (3 N, 0.3 N m, in the sensor frame), as the cart paper's hardware.
PUSH_SENSOR_NOISE = MeasurementNoise(position=0.003, theta=0.003, velocity=0.01, omega=0.01, force=3.0, torque=0.3)


@dataclass(frozen=True)
class PushConfig:
    """One closed-loop run: trajectory, robots, contact mode, estimator, truth, noise, seed."""

    trajectory: int = 2
    duration: float = 30.0
    dt: float = 0.01
    substeps: int = 2
    n_arms: int = 1
    estimation: bool = True
    contact: str = "optimal"
    fixed_contact_y: Tuple[float, ...] = (-0.2,)
    true_params: CartParams = TRUE_CART
    initial_mass: float = 16.0
    initial_com: Tuple[float, float] = (0.3, 0.0)
    controller: str = "kanayama"
    noise: MeasurementNoise = PUSH_SENSOR_NOISE
    seed: int = 0
    replan_period: float = 0.5
    replan_horizon: float = 3.0
    slide_speed: float = 0.05
    arm_limits: ArmLimits = ArmLimits()

    def __post_init__(self) -> None:
        if self.trajectory not in (1, 2):
            raise WholeBodyError(f"trajectory must be 1 or 2, got {self.trajectory}")
        if self.n_arms not in (1, 2):
            raise WholeBodyError(f"arms must be 1 or 2, got {self.n_arms}")
        if self.contact not in ("fixed", "optimal"):
            raise WholeBodyError(f"contact must be 'fixed' or 'optimal', got {self.contact!r}")
        if not (self.dt > 0 and self.duration > 0 and self.initial_mass > 0):
            raise WholeBodyError("dt, duration and initial_mass must be positive")
        if len(self.fixed_contact_y) not in (1, 2):
            raise WholeBodyError("fixed_contact_y needs one value per arm")

    def contact_y0(self) -> np.ndarray:
        """Return the initial contact y per arm (fixed mode: the fixed points)."""
        ys = np.asarray(self.fixed_contact_y, dtype=float)
        if self.n_arms == 2 and ys.size == 1:
            ys = np.array([-0.2, 0.2])
        if self.n_arms == 1:
            ys = ys[:1]
        return np.sort(ys)

    def initial_params(self) -> CartParams:
        """Return the controller's/estimator's initial guess (mass, CoM given; inertia scaled with the mass)."""
        return CartParams(self.initial_mass, self.initial_com[0], self.initial_com[1],
                          self.true_params.I * self.initial_mass / self.true_params.m, self.true_params.sigma)

    def make_trajectory(self) -> UnicycleTrajectory:
        """Return Traj. 1 or 2 of the paper with this run's duration."""
        return trajectory_1(self.duration) if self.trajectory == 1 else trajectory_2(self.duration)


@dataclass(frozen=True)
class PushMetrics:
    """Scalar results of one run (the CLI's JSON fields)."""

    tracking_rms_m: float
    tracking_max_m: float
    arm_torque_rms_nm: float
    arm_torque_peak_nm: float
    arm_push_torque_rms_nm: float
    arm_torque_limit_ratio: float
    ee_force_rms_n: float
    ee_force_peak_n: float
    ee_torque_rms_nm: float
    mass_error_final_kg: float
    com_error_final_m: float
    mass_final_kg: float
    grasp_error_max_m: float
    base_twist_limit_ratio: float
    base_wheel_limit_ratio: float
    saturated_steps: int

    def as_dict(self) -> dict:
        """Return the metrics as a JSON-ready dict."""
        return {k: (int(v) if isinstance(v, (int, np.integer)) else float(v)) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class PushResult:
    """Time histories of one run (N samples at t_k = k dt) and its metrics."""

    config: PushConfig
    t: np.ndarray
    q_true: np.ndarray  # (N, 3) cart pose
    qd_true: np.ndarray
    q_desired: np.ndarray
    z_meas: np.ndarray  # (N, 6) motion capture
    gamma_desired: np.ndarray  # (N, 3) controller output
    gamma_applied: np.ndarray  # (N, 3) produced by the hands (true)
    gamma_measured: np.ndarray  # (N, 3) from the F/T sensors through the grasp map
    phi_hat: np.ndarray  # (N, 4) estimate used by the controller at t_k
    contact_y: np.ndarray  # (N, n_arms)
    wrenches: np.ndarray  # (N, n_arms, 6) hand wrenches in {a}
    arm_torque: np.ndarray  # (N, n_arms, 7)
    push_torque: np.ndarray  # (N, n_arms, 7) the J^T w part
    robot_x: np.ndarray  # (N, n_arms, 10) base pose + arm joints
    grasp_error: np.ndarray  # (N, n_arms) ee position error w.r.t. the handle point
    effort_limit: np.ndarray  # (7,)
    metrics: PushMetrics


# ------------------------------------------------------------------------------------- robot side
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


def grasp_target(q_cart: np.ndarray, qd_cart: np.ndarray, y: float, ydot: float,
                 R_b_ee: np.ndarray) -> Tuple[pin.SE3, np.ndarray]:
    """Return (world pose of the grasp frame, its spatial velocity (v, w) world-aligned at the grasp point)."""
    T_sb = cart_se3(q_cart)
    p_b = handle_point(y)
    T = T_sb * pin.SE3(R_b_ee, p_b)
    r = T_sb.rotation @ p_b
    om = qd_cart[2]
    v = np.array([qd_cart[0] - om * r[1], qd_cart[1] + om * r[0], 0.0]) + T_sb.rotation @ np.array([0.0, ydot, 0.0])
    return T, np.concatenate([v, [0.0, 0.0, om]])


def base_target(q_cart: np.ndarray, qd_cart: np.ndarray, offset_b: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Return (planar pose, world rates) of a base rigidly offset by offset_b = (x, y) in {b}, same heading."""
    c, s = math.cos(q_cart[2]), math.sin(q_cart[2])
    px, py = c * offset_b[0] - s * offset_b[1], s * offset_b[0] + c * offset_b[1]
    om = qd_cart[2]
    pose = np.array([q_cart[0] + px, q_cart[1] + py, q_cart[2]])
    return pose, np.array([qd_cart[0] - om * py, qd_cart[1] + om * px, om])


#: Whole-body QP settings of the push (task weight 1; the posture and base pulls are 1e-4 and 1e-3 of it).
PUSH_CONTROLLER = ControllerConfig(gain=20.0, damping=1e-7, secondary="posture", secondary_weight=1e-4,
                                   posture_gain=1.0, max_linear_speed=3.0, max_angular_speed=3.0,
                                   limit_margin=0.05, solver="daqp", fallback_solver="proxqp",
                                   base_weight=1e-3, base_gain=2.0)


class WholeBodyQPTracker:
    """`BodyTracker` of the project's whole-body QP (`wholebody.control.ResolvedRateController`).

    The grasp frame follows the handle (feed-forward + `gain` feedback), the arm is pulled to its
    grasp posture, and the base to its nominal place behind its contact point (the controller's
    base regularisation). Bounds: joint positions/rates, and the Ridgeback's wheel speeds (which
    imply its twist limits 1.1 m/s, 1.1 m/s, 2 rad/s).
    """

    def __init__(self, wb: WholeBody, q_nominal: np.ndarray, config: ControllerConfig = PUSH_CONTROLLER) -> None:
        self.controller = ResolvedRateController(wb, config, posture=q_nominal)
        self.last: Optional[StepResult] = None

    def step(self, x: np.ndarray, target: pin.SE3, target_velocity: np.ndarray, base_target: np.ndarray,
             base_velocity: np.ndarray, dt: float) -> np.ndarray:
        """Return u = [arm rates (7), base body twist (3)] for one period."""
        res = self.controller.step(x, target, target_velocity, dt, base_target=base_target,
                                   base_target_velocity=base_velocity)
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
        raise WholeBodyError(f"the arm cannot reach the handle from base pose {np.round(base_pose, 3)} "
                             f"(residual {np.linalg.norm(sol.fun):.3g})")
    return sol.x


class MobileManipulator:
    """One Ridgeback + iiwa holding the handle: state, tracking, dynamics, F/T sensing."""

    def __init__(self, robot: robots.LoadedRobot, q_cart: np.ndarray, contact_y: float, base_y: float,
                 R_b_ee: np.ndarray, tracker: Optional[BodyTracker] = None) -> None:
        self.wb = wholebody_for(robot, base_input="twist")
        self.model = self.wb.model
        self.data = self.model.createData()
        self.R_b_ee = R_b_ee
        self.base_offset_y = base_y - contact_y
        self.ee_id = self.wb.ee_frame_id
        self.ft_id = robot.frame_id("ft_sensor")
        self.offset = np.array([handle_point(contact_y)[0] + BASE_OFFSET_X, base_y])
        pose, _ = base_target(q_cart, np.zeros(3), self.offset)
        target, _ = grasp_target(q_cart, np.zeros(3), contact_y, 0.0, R_b_ee)
        qa = solve_grasp_ik(self.wb, pose, target, ARM_SEED)
        self.x = np.r_[pose, qa]
        self.tracker = tracker if tracker is not None else WholeBodyQPTracker(self.wb, qa)
        self.u = np.zeros(self.wb.n_u)
        self.effort_limit = self.model.effortLimit[self.wb.arm_idx_v].copy()

    def pin_state(self, u: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Return Pinocchio (q, v) for the current x and input u (wheel joints left at rest)."""
        q = self.wb.to_pinocchio_q(self.x)
        v = np.zeros(self.model.nv)
        v[0:3] = u[self.wb.n_arm:]  # planar root joint: body twist
        v[self.wb.arm_idx_v] = u[:self.wb.n_arm]
        return q, v

    def torques(self, u: np.ndarray, u_prev: np.ndarray, dt: float, wrench_world: np.ndarray
                ) -> Tuple[np.ndarray, np.ndarray, pin.SE3, pin.SE3]:
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


def ft_measurement(wrench_world: np.ndarray, oMee: pin.SE3, oMft: pin.SE3, rng: np.random.Generator,
                   noise: MeasurementNoise) -> pin.Force:
    """Return the F/T sensor reading (sensor frame, at its origin) of a hand wrench, plus white noise."""
    at_origin = pin.SE3(np.eye(3), oMee.translation).act(pin.Force(wrench_world[:3], wrench_world[3:]))
    local = oMft.actInv(at_origin)
    return pin.Force(local.linear + rng.normal(0.0, noise.force, 3), local.angular + rng.normal(0.0, noise.torque, 3))


def ft_to_cart_gamma(reading: pin.Force, oMft: pin.SE3, q_cart_meas: np.ndarray) -> np.ndarray:
    """Return Gamma_MM (fx, fy in {s}, tau about the measured {b} origin) of one F/T reading (eq. 23–24)."""
    world = oMft.act(reading)
    at_b = pin.SE3(np.eye(3), np.array([q_cart_meas[0], q_cart_meas[1], 0.0])).actInv(world)
    return np.array([at_b.linear[0], at_b.linear[1], at_b.angular[2]])


# ------------------------------------------------------------------------------------- contacts
class ContactScheduler:
    """Contact points on the handle: fixed, or re-planned from the estimate and slid towards the plan."""

    def __init__(self, config: PushConfig, trajectory: UnicycleTrajectory, controller_name: str) -> None:
        self.config = config
        self.trajectory = trajectory
        self.y = config.contact_y0().copy()
        self.plan = self.y.copy()
        self.next_replan = 0.0
        self.alloc = WrenchAllocator([handle_point(v) for v in self.y], config.arm_limits,
                                     only_motion_directions=True)
        self.handle = HandleSegment.default()
        n = config.n_arms
        grid = np.round(np.arange(-0.25, 0.2501, 0.025 if n == 1 else 0.05), 6)
        self.candidates = [np.array([g]) for g in grid] if n == 1 else [
            np.array([a, b]) for a in grid for b in grid if b - a >= 0.2 - 1e-9]

    def _planned_wrenches(self, t: float, params: CartParams) -> List[np.ndarray]:
        """Return the feed-forward body wrenches (fx_b, 0, tau_b) along the next replan_horizon seconds."""
        out = []
        ts = t + np.linspace(0.0, self.config.replan_horizon, 7)
        m, a, b, j = params.phi
        for tk in ts:
            _, qd_d, qdd_d = self.trajectory.sample(tk)
            th = math.atan2(qd_d[1], qd_d[0]) if np.hypot(qd_d[0], qd_d[1]) > 1e-6 else self.trajectory.yaw(tk)[0]
            c, s = math.cos(th), math.sin(th)
            v = c * qd_d[0] + s * qd_d[1]
            vdot = c * qdd_d[0] + s * qdd_d[1]
            om, odot = qd_d[2], qdd_d[2]
            fu, tau = inverse_dynamics(v, om, vdot, odot, m, a, b, j, *params.damping)
            out.append(np.array([fu, 0.0, tau]))
        return out

    def update(self, t: float, params: CartParams, dt: float) -> Tuple[np.ndarray, np.ndarray]:
        """Return (contact y per arm, their rates) after one period."""
        if self.config.contact == "fixed":
            return self.y, np.zeros_like(self.y)
        if t >= self.next_replan - 1e-12:
            self.next_replan = t + self.config.replan_period
            gammas = self._planned_wrenches(t, params)
            best, best_v = self.plan, np.inf
            for cand in self.candidates:
                self.alloc.set_points([handle_point(v) for v in cand])
                total = 0.0
                for g in gammas:
                    res = self.alloc.solve(g, raise_on_infeasible=False)
                    total += res.effort + 1e6 * res.residual ** 2
                if total < best_v - 1e-9:
                    best, best_v = cand, total
            self.plan = best.copy()
        step = np.clip(self.plan - self.y, -self.config.slide_speed * dt, self.config.slide_speed * dt)
        self.y = self.y + step
        return self.y, step / dt


# ------------------------------------------------------------------------------------- the loop
def make_estimator(config: PushConfig, q0: np.ndarray) -> CartEKF:
    """Return the EKF (parameters frozen at the initial guess when estimation is off)."""
    p0 = config.initial_params()
    ekf_config = EKFConfig.from_noise(config.noise.measurement_std(), estimate_params=config.estimation)
    return CartEKF(q0, np.zeros(3), p0.phi, p0.sigma, ekf_config)


def run_push(config: PushConfig = PushConfig(), controller: Optional[CartController] = None,
             estimator: Optional[ParameterEstimator] = None, progress: bool = False) -> PushResult:
    """Return the time histories and metrics of one closed-loop push (see the module docstring)."""
    rng = np.random.default_rng(config.seed)
    traj = config.make_trajectory()
    controller = controller if controller is not None else make_controller(config.controller, traj)
    truth = config.true_params
    q, qd, _ = traj.sample(0.0)
    qd = qd.copy()
    estimator = estimator if estimator is not None else make_estimator(config, q)
    scheduler = ContactScheduler(config, traj, config.controller)
    R_b_ee = grasp_rotation()
    robot = robots.load("ridgeback_iiwa")
    ys = scheduler.y
    if config.n_arms == 1:
        base_ys = [ys[0]]
    else:
        base_ys = [ys[0] - TWO_ARM_BASE_SPREAD, ys[1] + TWO_ARM_BASE_SPREAD]
    mms = [MobileManipulator(robot, q, y, by, R_b_ee) for y, by in zip(ys, base_ys)]
    for mm, by in zip(mms, base_ys):
        mm.base_y = by
    allocator = WrenchAllocator([handle_point(v) for v in ys], config.arm_limits, only_motion_directions=True)

    n = int(round(config.duration / config.dt)) + 1
    na = config.n_arms
    dt = config.dt
    h = dt / config.substeps
    H = {k: np.zeros(s) for k, s in dict(
        q_true=(n, 3), qd_true=(n, 3), q_desired=(n, 3), z_meas=(n, 6), gamma_desired=(n, 3),
        gamma_applied=(n, 3), gamma_measured=(n, 3), phi_hat=(n, 4), contact_y=(n, na), wrenches=(n, na, 6),
        arm_torque=(n, na, 7), push_torque=(n, na, 7), robot_x=(n, na, 10), grasp_error=(n, na),
        base_ratio=(n, na), wheel_ratio=(n, na)).items()}
    saturated = 0
    std = config.noise.measurement_std()
    z = np.r_[q, qd] + rng.normal(0.0, 1.0, 6) * std
    iterator = range(n)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc="push", leave=False)
    for k in iterator:
        t = k * dt
        params_hat = estimator.params()
        q_hat, qd_hat = estimator.x[0:3].copy(), estimator.x[3:6].copy()
        gamma_d = np.asarray(controller.gamma(t, q_hat, qd_hat, params_hat), dtype=float)  # paper eq. (26)
        ys, ydots = scheduler.update(t, params_hat, dt)
        allocator.set_points([handle_point(v) for v in ys])
        alloc = allocator.solve(cart_model.generalized_to_body(q, gamma_d), raise_on_infeasible=False)  # eq. (25)
        if alloc.residual > 1e-6 * max(1.0, float(np.abs(gamma_d).max())):
            saturated += 1
        W = alloc.wrenches_ee
        T_sb = cart_se3(q)
        gamma_true = np.zeros(3)
        gamma_meas = np.zeros(3)
        for i, mm in enumerate(mms):
            target, vel = grasp_target(q, qd, ys[i], ydots[i], R_b_ee)
            bpose, brates = base_target(q, qd, np.array([handle_point(ys[i])[0] + BASE_OFFSET_X, mm.base_y]))
            u = mm.tracker.step(mm.x, target, vel, bpose, brates, dt)
            w_world = np.concatenate([T_sb.rotation @ W[i, :3], T_sb.rotation @ W[i, 3:]])
            tau, push, oMee, oMft = mm.torques(u, mm.u, dt, w_world)
            gamma_true += cart_model.contact_wrench_to_generalized(q, handle_point(ys[i]), W[i, :2], W[i, 5])
            reading = ft_measurement(w_world, oMee, oMft, rng, config.noise)
            gamma_meas += ft_to_cart_gamma(reading, oMft, z[:3])
            H["arm_torque"][k, i] = tau
            H["push_torque"][k, i] = push
            H["robot_x"][k, i] = mm.x
            H["grasp_error"][k, i] = np.linalg.norm(oMee.translation - target.translation)
            H["base_ratio"][k, i] = np.max(np.abs(u[mm.wb.n_arm:]) / BASE_TWIST_LIMIT)
            H["wheel_ratio"][k, i] = np.max(np.abs(mm.wb.wheel_rates(u)) / mm.wb.wheel_velocity_limit)
            H["wrenches"][k, i] = W[i]
            mm.x = mm.wb.integrate(mm.x, u, dt)
            mm.u = u
        q_d, _, _ = traj.sample(t)
        for key, val in (("q_true", q), ("qd_true", qd), ("q_desired", q_d), ("z_meas", z),
                         ("gamma_desired", gamma_d), ("gamma_applied", gamma_true),
                         ("gamma_measured", gamma_meas), ("phi_hat", params_hat.phi), ("contact_y", ys)):
            H[key][k] = val
        if k == n - 1:
            break
        for j in range(config.substeps):
            q, qd = rk4_step(t + j * h, q, qd, gamma_true, truth, h)
        z = np.r_[q, qd] + rng.normal(0.0, 1.0, 6) * std
        estimator.step(gamma_meas, dt, z)
    t_arr = np.arange(n) * dt
    effort_limit = mms[0].effort_limit
    metrics = _metrics(config, H, effort_limit, estimator.params(), saturated)
    return PushResult(config=config, t=t_arr, q_true=H["q_true"], qd_true=H["qd_true"], q_desired=H["q_desired"],
                      z_meas=H["z_meas"], gamma_desired=H["gamma_desired"], gamma_applied=H["gamma_applied"],
                      gamma_measured=H["gamma_measured"], phi_hat=H["phi_hat"], contact_y=H["contact_y"],
                      wrenches=H["wrenches"], arm_torque=H["arm_torque"], push_torque=H["push_torque"],
                      robot_x=H["robot_x"], grasp_error=H["grasp_error"], effort_limit=effort_limit,
                      metrics=metrics)


def _metrics(config: PushConfig, H: dict, effort_limit: np.ndarray, final: CartParams, saturated: int) -> PushMetrics:
    err = np.hypot(H["q_true"][:, 0] - H["q_desired"][:, 0], H["q_true"][:, 1] - H["q_desired"][:, 1])
    tau = H["arm_torque"]
    f = np.linalg.norm(H["wrenches"][:, :, :3], axis=2)
    tz = np.linalg.norm(H["wrenches"][:, :, 3:], axis=2)
    truth = config.true_params
    return PushMetrics(
        tracking_rms_m=float(np.sqrt(np.mean(err ** 2))),
        tracking_max_m=float(err.max()),
        arm_torque_rms_nm=float(np.sqrt(np.mean(tau ** 2))),
        arm_torque_peak_nm=float(np.abs(tau).max()),
        arm_push_torque_rms_nm=float(np.sqrt(np.mean(H["push_torque"] ** 2))),
        arm_torque_limit_ratio=float(np.max(np.abs(tau) / effort_limit)),
        ee_force_rms_n=float(np.sqrt(np.mean(f ** 2))),
        ee_force_peak_n=float(f.max()),
        ee_torque_rms_nm=float(np.sqrt(np.mean(tz ** 2))),
        mass_error_final_kg=float(abs(final.m - truth.m)),
        com_error_final_m=float(np.hypot(final.dx - truth.dx, final.dy - truth.dy)),
        mass_final_kg=float(final.m),
        grasp_error_max_m=float(H["grasp_error"].max()),
        base_twist_limit_ratio=float(H["base_ratio"].max()),
        base_wheel_limit_ratio=float(H["wheel_ratio"].max()),
        saturated_steps=int(saturated),
    )
