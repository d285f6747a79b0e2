"""The closed loop: mobile manipulator(s) push the cart, the EKF closes the loop (cart paper §II–III).

One control period ``dt`` (100 Hz by default):

1. cart controller (``cart.control``, using the current parameter estimate)
   -> desired cart wrench Gamma_MM (paper eq. 26);
2. contact points on the handle (fixed, or re-planned every ``replan_period``
   from the estimated model and slid towards the plan at ``slide_speed``) and
   the wrench allocation QP (``wholebody.contacts.allocation``, paper eq. 25) ->
   end-effector wrenches;
3. arm joint torques ``tau = rnea(q, v, a) + J^T w`` (Pinocchio; the arm's own
   gravity and dynamics plus the push), checked against the iiwa's effortLimit;
4. each mobile manipulator's base + arm follow the grasp point on the moving
   handle with the project's whole-body QP (``wholebody.motion.control``, through the
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

from dataclasses import dataclass
from collections.abc import Sequence

import numpy as np

import robots
from cart import model as cart_model
from cart.control import make_controller
from cart.ekf import CartEKF, EKFConfig
from cart.params import CartParams
from cart.simulate import rk4_step
from wholebody.contacts.allocation import WrenchAllocator
from wholebody.push.config import CartController, ParameterEstimator, PushConfig, PushMetrics, PushResult
from robots.profiles import profile
from wholebody.errors import WholeBodyError
from wholebody.push.robot import (
    TWO_ARM_BASE_SPREAD,
    MobileManipulator,
    base_target,
    cart_se3,
    ft_measurement,
    ft_to_cart_gamma,
    grasp_rotation,
    grasp_target,
    handle_point,
)
from wholebody.push.scheduler import ContactScheduler


def make_estimator(config: PushConfig, q0: np.ndarray) -> CartEKF:
    """Return the EKF (parameters frozen at the initial guess when estimation is off)."""
    p0 = config.initial_params()
    ekf_config = EKFConfig.from_noise(config.noise.measurement_std(), estimate_params=config.estimation)
    return CartEKF(q0, np.zeros(3), p0.phi, p0.sigma, ekf_config)


@dataclass
class PushHistory:
    """The run's time histories, filled one period at a time (N samples, n_arms robots)."""

    q_true: np.ndarray
    qd_true: np.ndarray
    q_desired: np.ndarray
    z_meas: np.ndarray
    gamma_desired: np.ndarray
    gamma_applied: np.ndarray
    gamma_measured: np.ndarray
    phi_hat: np.ndarray
    contact_y: np.ndarray
    wrenches: np.ndarray
    arm_torque: np.ndarray
    push_torque: np.ndarray
    robot_x: np.ndarray
    grasp_error: np.ndarray
    base_ratio: np.ndarray
    wheel_ratio: np.ndarray
    base_twist: np.ndarray
    wheel_rates: np.ndarray
    param_std: np.ndarray
    saturated: int = 0

    @classmethod
    def empty(cls, n: int, n_arms: int, n_wheels: int = 4) -> PushHistory:
        """Return zero histories for n samples."""
        na = n_arms
        shapes = dict(
            q_true=(n, 3),
            qd_true=(n, 3),
            q_desired=(n, 3),
            z_meas=(n, 6),
            gamma_desired=(n, 3),
            gamma_applied=(n, 3),
            gamma_measured=(n, 3),
            phi_hat=(n, 4),
            contact_y=(n, na),
            wrenches=(n, na, 6),
            arm_torque=(n, na, 7),
            push_torque=(n, na, 7),
            robot_x=(n, na, 10),
            grasp_error=(n, na),
            base_ratio=(n, na),
            wheel_ratio=(n, na),
            base_twist=(n, na, 3),
            wheel_rates=(n, na, n_wheels),
            param_std=(n, 2),
        )
        return cls(**{k: np.zeros(shape) for k, shape in shapes.items()})


@dataclass
class ControlStep:
    """What the cart side decides in one period: the desired wrench, the contacts and the hand wrenches."""

    params_hat: CartParams
    gamma_desired: np.ndarray
    contact_y: np.ndarray
    contact_rates: np.ndarray
    wrenches_ee: np.ndarray  # (n_arms, 6) in {a}


def make_robots(
    config: PushConfig,
    q_cart: np.ndarray,
    contact_y: np.ndarray,
    seeds: Sequence[np.ndarray | None] | None = None,
) -> list[MobileManipulator]:
    """Return the mobile manipulators holding the handle at `contact_y` (two: bases spread apart).

    Everything robot-specific (joints, grasp pitch, base place, seeds) comes from `robots.profiles`.
    """
    robot = robots.load(config.robot)
    prof = profile(config.robot)
    ys = contact_y
    if prof.push_base_y is not None:  # the base stands at a fixed place behind the cart
        if config.n_arms != 1:
            raise WholeBodyError(f"robot {config.robot!r} pushes alone (its base stands at a fixed place); use 1 arm")
        base_ys = [prof.push_base_y]
    else:
        base_ys = [ys[0]] if config.n_arms == 1 else [ys[0] - TWO_ARM_BASE_SPREAD, ys[1] + TWO_ARM_BASE_SPREAD]
    R_b_ee = grasp_rotation(prof.grasp_pitch)
    seeds = seeds if seeds is not None else [None] * len(ys)
    return [MobileManipulator(robot, q_cart, y, by, R_b_ee, arm_seed=sd) for y, by, sd in zip(ys, base_ys, seeds)]


def make_reach_map(config: PushConfig):
    """Return the `ReachMap` of a robot whose base stands at a fixed place behind the cart (None otherwise)."""
    from wholebody.contacts.placement import reach_map
    from wholebody.motion.kinematics import wholebody_for

    prof = profile(config.robot)
    if prof.push_base_y is None:  # the base follows the contact sideways: every handle point is held alike
        return None
    robot = robots.load(config.robot)
    wb = wholebody_for(robot, base_input=prof.base_input)
    R = grasp_rotation(prof.grasp_pitch)
    zero = np.zeros(3)
    offset = np.array([handle_point(0.0)[0] + prof.push_base_x, prof.push_base_y])
    return reach_map(
        wb,
        lambda y: base_target(zero, zero, offset)[0],
        lambda y: grasp_target(zero, zero, float(y), 0.0, R)[0],
        np.round(np.arange(-0.25, 0.2501, 0.025), 6),
        prof.push_arm_seed,
        0.0,
    )


def control_step(
    t: float,
    dt: float,
    q: np.ndarray,
    controller: CartController,
    estimator: ParameterEstimator,
    scheduler: ContactScheduler,
    allocator: WrenchAllocator,
) -> tuple[ControlStep, bool]:
    """Return (the period's decisions, whether the allocation saturated): controller eq. (26), allocation eq. (25)."""
    params_hat = estimator.params()
    q_hat, qd_hat = estimator.x[0:3].copy(), estimator.x[3:6].copy()
    gamma_d = np.asarray(controller.gamma(t, q_hat, qd_hat, params_hat), dtype=float)  # paper eq. (26)
    ys, ydots = scheduler.update(t, params_hat, dt)
    allocator.set_points([handle_point(v) for v in ys])
    alloc = allocator.solve(cart_model.generalized_to_body(q, gamma_d), raise_on_infeasible=False)  # eq. (25)
    saturated = alloc.residual > 1e-6 * max(1.0, float(np.abs(gamma_d).max()))
    return ControlStep(params_hat, gamma_d, ys, ydots, alloc.wrenches_ee), saturated


def robots_step(
    k: int,
    dt: float,
    q: np.ndarray,
    qd: np.ndarray,
    z: np.ndarray,
    step: ControlStep,
    mms: Sequence[MobileManipulator],
    hist: PushHistory,
    config: PushConfig,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Move each robot one period, record it; return (the wrench the hands apply, the F/T-measured one) as Gamma_MM."""
    T_sb = cart_se3(q)
    W = step.wrenches_ee
    gamma_true = np.zeros(3)
    gamma_meas = np.zeros(3)
    for i, mm in enumerate(mms):
        target, vel = grasp_target(q, qd, step.contact_y[i], step.contact_rates[i], mm.R_b_ee)
        bpose, brates = base_target(q, qd, mm.base_offset_b)
        u = mm.tracker.step(mm.x, target, vel, bpose, brates, dt)
        w_world = np.concatenate([T_sb.rotation @ W[i, :3], T_sb.rotation @ W[i, 3:]])
        tau, push, oMee, oMft = mm.torques(u, mm.u, dt, w_world)
        gamma_true += cart_model.contact_wrench_to_generalized(q, handle_point(step.contact_y[i]), W[i, :2], W[i, 5])
        reading = ft_measurement(w_world, oMee, oMft, rng, config.noise)
        gamma_meas += ft_to_cart_gamma(reading, oMft, z[:3])
        hist.arm_torque[k, i] = tau
        hist.push_torque[k, i] = push
        hist.robot_x[k, i] = mm.x
        hist.grasp_error[k, i] = np.linalg.norm(oMee.translation - target.translation)
        twist = mm.body_twist(u)
        lim = np.asarray(mm.profile.base_twist_limit)
        hist.base_ratio[k, i] = np.max(np.abs(twist)[lim > 0] / lim[lim > 0])
        hist.base_twist[k, i] = twist
        wheels = mm.wb.wheel_rates(u)
        hist.wheel_rates[k, i, : wheels.size] = wheels
        hist.wheel_ratio[k, i] = np.max(np.abs(wheels) / mm.wb.wheel_velocity_limit)
        hist.wrenches[k, i] = W[i]
        mm.x = mm.wb.integrate(mm.x, u, dt)
        mm.u = u
    return gamma_true, gamma_meas


def _iterations(n: int, progress: bool, label: str):
    """Return range(n), wrapped in a terminal progress bar when `progress` (`wholebody.progress`)."""
    if not progress:
        return range(n)
    from wholebody.progress import progress_bar

    return progress_bar(range(n), desc=label, unit="step", enabled=True)


def param_std(estimator: ParameterEstimator) -> np.ndarray:
    """Return the estimator's 1-sigma of (mass [kg], CoM [m]); NaN when it gives no covariance (`CartEKF.params_std`)."""
    std = getattr(estimator, "params_std", None)
    if std is None:
        return np.full(2, np.nan)
    s = std()
    return np.array([s["mass"], float(np.hypot(*s["com"]))])


def run_push(
    config: PushConfig = PushConfig(),
    controller: CartController | None = None,
    estimator: ParameterEstimator | None = None,
    progress: bool = False,
    progress_label: str = "push",
) -> PushResult:
    """Return the time histories and metrics of one closed-loop push (see the module docstring).

    ``progress``: show a progress bar on stderr (the CLI passes True only on a terminal without --json).
    """
    rng = np.random.default_rng(config.seed)
    traj = config.make_trajectory()
    controller = controller if controller is not None else make_controller(config.controller, traj)
    q, qd, _ = traj.sample(0.0)
    qd = qd.copy()
    estimator = estimator if estimator is not None else make_estimator(config, q)
    reach = make_reach_map(config)
    scheduler = ContactScheduler(config, traj, reach)
    seeds = None if reach is None else [reach.postures[reach.index(scheduler.y[0])]]
    mms = make_robots(config, q, scheduler.y, seeds)
    allocator = WrenchAllocator([handle_point(v) for v in scheduler.y], config.arm_limits, only_motion_directions=True)
    n = int(round(config.duration / config.dt)) + 1
    dt, h = config.dt, config.dt / config.substeps
    hist = PushHistory.empty(n, config.n_arms, mms[0].wb.wheel_velocity_limit.size)
    std = config.noise.measurement_std()
    z = np.r_[q, qd] + rng.normal(0.0, 1.0, 6) * std
    for k in _iterations(n, progress, progress_label):
        t = k * dt
        step, saturated = control_step(t, dt, q, controller, estimator, scheduler, allocator)
        hist.saturated += int(saturated)
        gamma_true, gamma_meas = robots_step(k, dt, q, qd, z, step, mms, hist, config, rng)
        q_d, _, _ = traj.sample(t)
        for key, val in (
            ("q_true", q),
            ("qd_true", qd),
            ("q_desired", q_d),
            ("z_meas", z),
            ("gamma_desired", step.gamma_desired),
            ("gamma_applied", gamma_true),
            ("gamma_measured", gamma_meas),
            ("phi_hat", step.params_hat.phi),
            ("contact_y", step.contact_y),
            ("param_std", param_std(estimator)),
        ):
            getattr(hist, key)[k] = val
        if k == n - 1:
            break
        for j in range(config.substeps):  # the true cart under the hands' wrench
            q, qd = rk4_step(t + j * h, q, qd, gamma_true, config.true_params, h)
        z = np.r_[q, qd] + rng.normal(0.0, 1.0, 6) * std  # motion capture
        estimator.step(gamma_meas, dt, z)  # paper eq. (8-20)
    return _result(config, hist, mms[0].effort_limit, estimator.params(), mms[0].wb.wheel_velocity_limit)


_RESULT_FIELDS = (
    "q_true",
    "qd_true",
    "q_desired",
    "z_meas",
    "gamma_desired",
    "gamma_applied",
    "gamma_measured",
    "phi_hat",
    "contact_y",
    "wrenches",
    "arm_torque",
    "push_torque",
    "robot_x",
    "grasp_error",
    "base_twist",
    "wheel_rates",
    "param_std",
)


def _result(
    config: PushConfig, hist: PushHistory, effort_limit: np.ndarray, final: CartParams, wheel_limit: np.ndarray
) -> PushResult:
    n = hist.q_true.shape[0]
    return PushResult(
        config=config,
        t=np.arange(n) * config.dt,
        effort_limit=effort_limit,
        wheel_velocity_limit=wheel_limit,
        metrics=_metrics(config, hist, effort_limit, final),
        **{key: getattr(hist, key) for key in _RESULT_FIELDS},
    )


def _metrics(config: PushConfig, H: PushHistory, effort_limit: np.ndarray, final: CartParams) -> PushMetrics:
    err = np.hypot(H.q_true[:, 0] - H.q_desired[:, 0], H.q_true[:, 1] - H.q_desired[:, 1])
    tau = H.arm_torque
    f = np.linalg.norm(H.wrenches[:, :, :3], axis=2)
    tz = np.linalg.norm(H.wrenches[:, :, 3:], axis=2)
    truth = config.true_params
    wheels = H.wheel_rates
    wheel_acc = np.diff(wheels, axis=0) / config.dt if wheels.shape[0] > 1 else np.zeros(1)
    dtau = np.diff(tau, axis=0) if tau.shape[0] > 1 else np.zeros(1)
    est = _estimation_metrics(config, H)
    return PushMetrics(
        tracking_rms_mm=float(1e3 * np.sqrt(np.mean(err**2))),
        tracking_max_mm=float(1e3 * err.max()),
        arm_torque_rms_nm=float(np.sqrt(np.mean(tau**2))),
        arm_torque_peak_nm=float(np.abs(tau).max()),
        arm_push_torque_rms_nm=float(np.sqrt(np.mean(H.push_torque**2))),
        arm_torque_limit_ratio=float(np.max(np.abs(tau) / effort_limit)),
        ee_force_rms_n=float(np.sqrt(np.mean(f**2))),
        ee_force_peak_n=float(f.max()),
        ee_torque_rms_nm=float(np.sqrt(np.mean(tz**2))),
        mass_error_final_kg=float(abs(final.m - truth.m)),
        com_error_final_m=float(np.hypot(final.dx - truth.dx, final.dy - truth.dy)),
        mass_final_kg=float(final.m),
        grasp_error_max_m=float(H.grasp_error.max()),
        base_twist_limit_ratio=float(H.base_ratio.max()),
        base_wheel_limit_ratio=float(H.wheel_ratio.max()),
        saturated_steps=int(H.saturated),
        base_wheel_speed_rms_rad_s=float(np.sqrt(np.mean(wheels**2))),
        base_wheel_speed_max_rad_s=float(np.abs(wheels).max()),
        base_wheel_acceleration_max_rad_s2=float(np.abs(wheel_acc).max()),
        base_lateral_speed_max_m_s=float(np.abs(H.base_twist[:, :, 1]).max()),
        arm_torque_step_max_nm=float(np.abs(dtau).max()),
        **est,
    )


def _estimation_metrics(config: PushConfig, H: PushHistory, after: float = 5.0) -> dict:
    """Return time-resolved estimation errors: RMS over the run, max after `after` s, time within 1 kg / 1 cm."""
    truth = config.true_params
    t = np.arange(H.phi_hat.shape[0]) * config.dt
    m = H.phi_hat[:, 0]
    m_safe = np.where(np.abs(m) > 1e-9, m, np.nan)
    e_m = np.abs(m - truth.m)
    e_c = np.hypot(H.phi_hat[:, 1] / m_safe - truth.dx, H.phi_hat[:, 2] / m_safe - truth.dy)
    late = t >= after
    late = late if late.any() else np.ones_like(late)
    return dict(
        mass_error_rms_kg=float(np.sqrt(np.mean(e_m**2))),
        mass_error_max_after_5s_kg=float(e_m[late].max()),
        com_error_rms_m=float(np.sqrt(np.nanmean(e_c**2))),
        com_error_max_after_5s_m=float(np.nanmax(e_c[late])),
        time_mass_within_1kg_s=float(np.sum(e_m <= 1.0) * config.dt),
        time_com_within_1cm_s=float(np.sum(e_c <= 0.01) * config.dt),
        mass_unobservable_s=unobservable_intervals(t, H.param_std[:, 0]) if config.estimation else (),
        com_unobservable_s=unobservable_intervals(t, H.param_std[:, 1]) if config.estimation else (),
    )


def unobservable_intervals(
    t: np.ndarray, std: np.ndarray, window: float = 0.5, min_length: float = 1.0
) -> tuple[tuple[float, float], ...]:
    """Return the stretches [t0, t1] (s, >= `min_length` long) over which the EKF's 1-sigma `std` of a parameter grew.

    The time t_k - window/2 is flagged when std(t_k) > std(t_k - window): around it
    the measurements brought less information about the parameter than the EKF's
    random-walk process noise (``EKFConfig.q_phi``) took away, i.e. the parameter was
    not observable from the pushes (no acceleration for the mass, no turning for the
    CoM). Consecutive flagged times form a stretch; NaN std gives none.
    """
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    w = max(1, int(round(window / dt)))
    if len(t) <= w or not np.all(np.isfinite(std)):
        return ()
    flagged = np.flatnonzero(std[w:] > std[:-w])
    if flagged.size == 0:
        return ()
    centre = t[flagged + w] - 0.5 * w * dt
    breaks = np.flatnonzero(np.diff(flagged) > 1)
    starts, ends = np.r_[0, breaks + 1], np.r_[breaks, flagged.size - 1]
    return tuple(
        (round(float(centre[a]), 2), round(float(centre[b]), 2))
        for a, b in zip(starts, ends)
        if centre[b] - centre[a] >= min_length - 1e-9
    )
