"""A push run: a loop of measure -> controller step -> plant step, recorded once per period.

The controller (`wholebody.push.controller.PushController`) holds the cart controller (eq. 26),
the estimator (eq. 8-20), the contact scheduler and the allocation (eq. 25) and the robots'
whole-body QPs; the plant answers its commands (`wholebody.push.kinematic_plant.KinematicPlant`:
ideal servos and the exact cart model; or any `wholebody.push.plant.SimulatedPlant`). The record of each
period (`StepRecord`) is written once; `run_push` stacks them into a `PushResult` with its metrics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from types import SimpleNamespace
from typing import Any
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

import robots
from robots.checks import frame_id

from cart.control import make_controller
from cart.ekf import CartEKF, EKFConfig
from cart.estimation_metrics import estimation_errors
from cart.params import CartParams
from wholebody.contacts.allocation import saturation_spans, saturation_summary
from wholebody.push.config import (
    LOST_TRACKING_M,
    CartController,
    ParameterEstimator,
    PushConfig,
    PushMetrics,
    PushResult,
)
from wholebody.push.geometry import DEFAULT_GEOMETRY
from wholebody.push.controller import ControlDecision, PushController
from wholebody.push.load_change import params_series
from wholebody.push.plants import make_plant, plant_report, plant_truth_schedule
from wholebody.push.plant import Measurement, RobotCommand, SimulatedPlant
from wholebody.push.reference_clock import ReferenceClock, ScaledReference
from wholebody.push import robot as robot_mod
from wholebody.push.robot import MobileManipulator
from wholebody.push.scheduler import ContactScheduler


def make_estimator(config: PushConfig, q0: np.ndarray) -> ParameterEstimator:
    """Return the run's estimator: the online least squares (default) or the paper's EKF (`config.estimator`).

    With estimation off, the paper's EKF with its parameters frozen at the initial guess (a state observer).
    """
    p0 = config.initial_params()
    std = config.noise.measurement_std()
    if config.estimation and config.estimator == "online":
        from cart.online_estimator import make_online_estimator

        return make_online_estimator(q0, p0, std, wrench_std=summed_wrench_std(config))
    ekf_config = EKFConfig.from_noise(std, estimate_params=config.estimation)
    return CartEKF(q0, np.zeros(3), p0.phi, p0.sigma, ekf_config)


def summed_wrench_std(config: PushConfig, sensors: np.ndarray | None = None) -> tuple[float, float]:
    """Return the white-noise std (forward force N, yaw torque N m) of the wrench the estimator sees.

    Each hand's F/T reading carries the sensor's white noise (``config.noise``: sf per force axis, st per torque
    axis, isotropic) at the sensor's origin; the controller carries every reading to {b}'s origin and sums them
    (`wholebody.push.robot.ft_to_cart_gamma`), so the force noise adds up over the hands and each sensor's force
    noise also reaches the yaw torque through the sensor's lever arm (x, y) in {b} (``sensors``, one row per hand;
    default `sensor_origins`): ``var_f = n sf^2``, ``var_tau = sum (st^2 + (x^2 + y^2) sf^2)``, one hand included.
    """
    sf, st = config.noise.force, config.noise.torque
    pts = sensor_origins(config) if sensors is None else np.asarray(sensors, dtype=float)
    lever = float(np.sum(pts[:, :2] ** 2))
    return math.sqrt(len(pts)) * sf, math.sqrt(len(pts) * st * st + lever * sf * sf)


def sensor_origins(config: PushConfig) -> np.ndarray:
    """Return the F/T sensors' origins (x, y) in {b} at the run's first grasps, one row per hand (n, 2).

    Each hand holds the handle point of its first contact with its grasp rotation (`wholebody.push.robot`); the
    sensor's origin sits at the gripper-to-sensor offset of the robot's model (its neutral configuration: exact
    when both frames ride the same joint, as in every shipped profile) from that grasp.
    """
    loaded = robots.load(config.robot)
    ys = np.sort(np.asarray(config.contact_y0(), dtype=float))
    prof = robot_mod.filled_profile(loaded)
    if robot_mod.arms_per_robot(loaded.profile or prof, len(ys)) > 1:  # one base, several arms (contacts by side)
        pl = robot_mod.multi_arm_placement(loaded, ys)
        tools = [prof.arms[i].tool_axis or "z" for i in pl.arms]
        grasps = [(i, robot_mod.grasp_rotation(pl.pitch, r, a)) for i, r, a in zip(pl.arms, pl.rolls, tools)]
    else:
        grasps = [(0, robot_mod.push_grasp_rotation(robot_mod.push_profile(loaded)))] * len(ys)
    model = loaded.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    geo = config.cart_geometry()
    out = []
    for y, (arm, R) in zip(ys, grasps):
        grip = data.oMf[frame_id(model, prof.arms[arm].gripper_frame)]
        offset = grip.actInv(data.oMf[frame_id(model, prof.arms[arm].sensor_frame)]).translation
        out.append((geo.point(float(y)) + R @ offset)[:2])
    return np.array(out)


def make_robots(
    config: PushConfig,
    q_cart: np.ndarray,
    contact_y: np.ndarray,
    seeds: Sequence[np.ndarray | None] | None = None,
    robot: robots.LoadedRobot | None = None,
) -> list[MobileManipulator]:
    """Return the mobile manipulators holding the handle at `contact_y` (`wholebody.push.robot.make_robots`).

    ``robot``: the loaded `config.robot` when the caller has it (loaded once per run)."""
    which = robot if robot is not None else config.robot
    return robot_mod.make_robots(
        which, q_cart, contact_y, seeds, geometry=config.cart_geometry(), placement_y=config.contact_y0()
    )


def make_reach_map(config: PushConfig, robot: robots.LoadedRobot | None = None):
    """Return the `ReachMap` of a robot whose base stands at a fixed place behind the cart (None otherwise); one
    per hand (a tuple) for one base holding the handle with several arms."""
    geo = config.cart_geometry()
    which = robot if robot is not None else config.robot
    if robot_mod.arms_per_robot(robots.profile(config.robot), config.n_arms) > 1:  # one base, several arms:
        if config.contact == "fixed":  # the placement holds the fixed contacts: nothing to plan
            return None
        loaded = which if isinstance(which, robots.LoadedRobot) else robots.load(which)  # one map per hand
        return robot_mod.multi_arm_reach_maps(loaded, config.contact_y0(), None if geo is DEFAULT_GEOMETRY else geo)
    return robot_mod.push_reach_map(which, None if geo is DEFAULT_GEOMETRY else geo)


def _iterations(n: int, progress: bool, label: str):
    """Return range(n), wrapped in a terminal progress bar when `progress` (`wholebody.progress`)."""
    if not progress:
        return range(n)
    from wholebody.progress import progress_bar

    return progress_bar(range(n), desc=label, unit="step", enabled=True)


@dataclass(frozen=True)
class StepRecord:
    """What one control period leaves behind (the fields of `PushResult`'s histories, written once)."""

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
    base_twist: np.ndarray
    wheel_rates: np.ndarray
    param_std: np.ndarray
    saturated: bool
    binding: str | None
    base_ratio: np.ndarray
    wheel_ratio: np.ndarray
    reference_time: float
    reference_rate: float


def stack_records(records: Sequence[StepRecord]) -> dict[str, Any]:
    """Return each `StepRecord` field stacked over the periods (first axis: time); ``binding``: a list."""
    out: dict[str, Any] = {
        f.name: np.array([getattr(r, f.name) for r in records]) for f in fields(StepRecord) if f.name != "binding"
    }
    out["binding"] = [r.binding for r in records]
    return out


@dataclass
class PushSetup:
    """A run's controller and the robots' initial states (what a plant needs to start from)."""

    controller: PushController
    #: (n_arms,) initial robot states x = [base pose, arm joints], holding the handle
    robot_x0: list[np.ndarray]
    q0: np.ndarray
    qd0: np.ndarray
    #: the configuration the controller was built for (a default contact out of reach moved, see `held_default_contact`)
    config: PushConfig | None = None
    #: sentences on what the set-up changed, for `wholebody.push.report.what_happened`
    notes: tuple[str, ...] = ()


def build_controller(
    config: PushConfig,
    controller: CartController | None = None,
    estimator: ParameterEstimator | None = None,
) -> PushSetup:
    """Return the push controller of `config` and the robots' initial grasp states at the trajectory's start.

    With time scaling (`PushConfig.scaling_settings`) the cart controller made here tracks the desired motion on
    the run's `ReferenceClock` (`ScaledReference`); a given `controller` is asked at the reference time."""
    traj = config.make_trajectory()
    scaling = config.scaling_settings()
    clock = None if scaling is None else ReferenceClock(scaling)
    if controller is None:
        controller = make_controller(config.controller, traj if clock is None else ScaledReference(traj, clock))
    q, qd, _ = traj.sample(0.0)
    robot = robots.load(config.robot)  # once per run: the reach map and the robots share it
    reach = make_reach_map(config, robot)
    scheduler = ContactScheduler(config, traj, reach)
    config, notes = held_default_contact(config, scheduler.y)
    if notes:  # the robots stand behind the contact they hold, as for a point the user gives
        scheduler = ContactScheduler(config, traj, reach)
    estimator = estimator if estimator is not None else make_estimator(config, q)
    seeds = None if reach is None or isinstance(reach, tuple) else [reach.postures[reach.index(scheduler.y[0])]]
    mms = make_robots(config, q, scheduler.y, seeds, robot)
    x0 = [mm.x.copy() for mm in mms]
    ctrl = PushController(config, controller, estimator, scheduler, mms, clock)
    return PushSetup(ctrl, x0, q.copy(), qd.copy(), config, notes)


def held_default_contact(config: PushConfig, held: np.ndarray) -> tuple[PushConfig, tuple[str, ...]]:
    """Return ``config`` holding the contacts ``held`` when its default fixed contact is out of the arm's reach.

    A robot's default contact (``fixed_contact_y`` not given) may lie off a cart file's handle or out of reach
    on it; `ContactScheduler` then holds the nearest point the arm holds with margin, and the run is set up as
    if the user had given that point (the robots stand behind it). A point the user gives is never moved.
    """
    default = config.contact_y0()
    if config.contact != "fixed" or config.fixed_contact_y is not None or np.allclose(held, default, atol=1e-9):
        return config, ()
    was = ", ".join(f"{v:.3f}" for v in default)
    now = ", ".join(f"{v:.3f}" for v in held)
    note = (
        f"contact: the robot's default contact y = {was} m is out of its arm's reach on this handle; held at y = "
        f"{now} m, the nearest point it holds with margin (choose one with --contact-y, PushConfig.fixed_contact_y)"
    )
    return replace(config, fixed_contact_y=tuple(float(v) for v in held)), (note,)


def record(
    plant: SimulatedPlant,
    m: Measurement,
    d: ControlDecision,
    cmds: Sequence[RobotCommand],
    q_desired: np.ndarray,
    mms: Sequence[MobileManipulator],
) -> StepRecord:
    """Return the period's record: the plant's truth, the measurement and the controller's decision."""
    q, qd = plant.cart_state()
    lim = [np.asarray(mm.profile.base_twist_limit) for mm in mms]
    return StepRecord(
        q_true=q,
        qd_true=qd,
        q_desired=q_desired,
        z_meas=m.z,
        gamma_desired=d.gamma_desired,
        gamma_applied=plant.cart_wrench(cmds),
        gamma_measured=d.gamma_measured,
        phi_hat=d.params_hat.phi,
        contact_y=d.contact_y,
        wrenches=d.wrenches_ee,
        arm_torque=d.arm_torque,
        push_torque=d.push_torque,
        robot_x=np.array(plant.robot_states()),
        grasp_error=d.grasp_error,
        base_twist=d.base_twist,
        wheel_rates=d.wheel_rates,
        param_std=d.param_std,
        saturated=d.saturated,
        binding=d.binding,
        base_ratio=np.array([np.max(np.abs(tw)[li > 0] / li[li > 0]) for tw, li in zip(d.base_twist, lim)]),
        wheel_ratio=np.array([np.max(np.abs(w) / mm.wb.wheel_velocity_limit) for w, mm in zip(d.wheel_rates, mms)]),
        reference_time=d.reference_time,
        reference_rate=d.reference_rate,
    )


def run_push(
    config: PushConfig = PushConfig(),
    controller: CartController | None = None,
    estimator: ParameterEstimator | None = None,
    progress: bool = False,
    progress_label: str = "push",
) -> PushResult:
    """Return the time histories and metrics of one closed-loop push on the kinematic plant.

    ``progress``: show a progress bar on stderr (the CLI passes True only on a terminal without --json).
    """
    setup = build_controller(config, controller, estimator)
    config = setup.config or config
    plant = make_plant(config, setup)
    result = run_loop(config, setup.controller, plant, progress, progress_label)
    return replace(
        result,
        plant_report=plant_report(plant),
        estimator_report=estimator_report(setup.controller.estimator),
        setup_notes=setup.notes,
    )


def run_loop(
    config: PushConfig,
    ctrl: PushController,
    plant: SimulatedPlant,
    progress: bool = False,
    progress_label: str = "push",
) -> PushResult:
    """Return the result of measure -> ``ctrl.step`` -> ``plant.step`` over the run's duration.

    The estimate is judged against the plant's truth (`wholebody.push.plants.plant_truth`); the tracking against
    the reference the controller followed (the desired motion at the reference time, `wholebody.push.reference_clock`).
    """
    traj = config.make_trajectory()
    n = int(round(config.duration / config.dt)) + 1
    records = []
    for k in _iterations(n, progress, progress_label):
        m = plant.measure()
        cmds = ctrl.step(m)
        assert ctrl.last is not None
        records.append(record(plant, m, ctrl.last, cmds, traj.sample(ctrl.last.reference_time)[0], ctrl.robots))
        if k == n - 1:
            break
        plant.step(cmds)
    H = stack_records(records)
    # the F/T-measured wrench of period k arrives with the measurement at t_{k+1}: align it with its period
    H["gamma_measured"] = np.r_[H["gamma_measured"][1:], H["gamma_measured"][-1:]]
    mm = ctrl.robots[0]
    schedule = plant_truth_schedule(config, plant)
    H["params_true"] = params_series(schedule, np.arange(len(records)) * config.dt)
    judged = replace(config, true_params=schedule[0][1])
    res = _result(judged, H, effort_limits(ctrl.robots), ctrl.estimator.params(), mm.wb.wheel_velocity_limit)
    return replace(res, robot_arms=mm.arms, load_changes_true=true_changes(config, schedule))


def true_changes(config: PushConfig, schedule: Sequence[tuple[float, CartParams]]) -> tuple[dict, ...]:
    """Return each load change the plant made (`PushConfig.load_changes`, in time order) with the time it took
    effect and the truth before and after it (`plant_truth_schedule`), JSON-ready."""
    changes = sorted(config.load_changes, key=lambda c: c.t)
    return tuple(
        {
            **c.as_dict(),
            "t_applied": float(t),
            "mass_before_kg": float(before.m),
            "mass_after_kg": float(after.m),
            "com_after_m": [float(after.dx), float(after.dy)],
        }
        for c, (_, before), (t, after) in zip(changes, schedule[:-1], schedule[1:])
    )


def effort_limits(mms: Sequence[MobileManipulator]) -> np.ndarray:
    """Return the arms' joint torque limits: (n_joints,) when every hand's arm has the same, else one row per
    hand (n_hands, n_joints), padded with inf where the arms' joint counts differ (the rows of `arm_torque`)."""
    rows = [mm.effort_limit[c] for mm in mms for c in mm.hand_cols]
    if all(r.shape == rows[0].shape and np.array_equal(r, rows[0]) for r in rows):
        return rows[0]
    width = max(len(r) for r in rows)
    return np.array([np.pad(r, (0, width - len(r)), constant_values=np.inf) for r in rows])


def estimator_report(estimator: ParameterEstimator) -> dict:
    """Return what the estimator says of its run: load changes, run-off flags, unexcited parameters (or {})."""
    report = getattr(estimator, "report", None)
    return dict(report()) if callable(report) else {}


def _result(
    config: PushConfig,
    hist: dict[str, Any],
    effort_limit: np.ndarray,
    final: CartParams,
    wheel_limit: np.ndarray,
) -> PushResult:
    n = hist["q_true"].shape[0]
    H = SimpleNamespace(**hist)
    return PushResult(
        config=config,
        t=np.arange(n) * config.dt,
        effort_limit=effort_limit,
        wheel_velocity_limit=wheel_limit,
        metrics=_metrics(config, H, effort_limit, final),
        **{k: v for k, v in hist.items() if k not in ("saturated", "binding", "base_ratio", "wheel_ratio")},
    )


def _metrics(config: PushConfig, H: SimpleNamespace, effort_limit: np.ndarray, final: CartParams) -> PushMetrics:
    err = np.hypot(H.q_true[:, 0] - H.q_desired[:, 0], H.q_true[:, 1] - H.q_desired[:, 1])
    tau = H.arm_torque
    f = np.linalg.norm(H.wrenches[:, :, :3], axis=2)
    tz = np.linalg.norm(H.wrenches[:, :, 3:], axis=2)
    truth = _final_truth(config, H)
    wheels = H.wheel_rates
    wheel_acc = np.diff(wheels, axis=0) / config.dt if wheels.shape[0] > 1 else np.zeros(1)
    dtau = np.diff(tau, axis=0) if tau.shape[0] > 1 else np.zeros(1)
    est = _estimation_metrics(config, H)
    return PushMetrics(
        tracking_rms_mm=float(1e3 * np.sqrt(np.mean(err**2))),
        tracking_max_mm=float(1e3 * err.max()),
        tracking_lost_at_s=_lost_at(err, config.dt),
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
        saturated_steps=int(np.sum(H.saturated)),
        saturation=saturation_summary(saturation_spans(np.arange(len(H.binding)) * config.dt, H.binding, config.dt)),
        reference_time_scale_min=float(H.reference_rate.min()),
        reference_slowed_s=float(np.sum(H.reference_rate < 1.0) * config.dt),
        reference_delay_s=float(max(0.0, (len(H.reference_time) - 1) * config.dt - H.reference_time[-1])),
        base_wheel_speed_rms_rad_s=float(np.sqrt(np.mean(wheels**2))),
        base_wheel_speed_max_rad_s=float(np.abs(wheels).max()),
        base_wheel_acceleration_max_rad_s2=float(np.abs(wheel_acc).max()),
        base_lateral_speed_max_m_s=float(np.abs(H.base_twist[:, :, 1]).max()),
        arm_torque_step_max_nm=float(np.abs(dtau).max()),
        **est,
    )


def _lost_at(err: np.ndarray, dt: float) -> float | None:
    """Return the first time (s) the tracking error exceeds `LOST_TRACKING_M`, or None."""
    lost = np.flatnonzero(err > LOST_TRACKING_M)
    return None if lost.size == 0 else round(float(lost[0] * dt), 3)


def _final_truth(config: PushConfig, H: SimpleNamespace) -> CartParams:
    """Return the truth at the run's end: after the last load change (`params_true`), else the config's."""
    truth = getattr(H, "params_true", None)
    if truth is None:
        return config.true_params
    m, dx, dy, inertia, sigma = (float(v) for v in truth[-1])
    return CartParams(m, dx, dy, inertia, sigma, config.true_params.sigma_yaw)


def _estimation_metrics(config: PushConfig, H: SimpleNamespace, after: float = 5.0) -> dict:
    """Return time-resolved estimation errors (`cart.estimation_metrics`) against the truth at each instant
    (`PushResult.params_true`: it steps at each load change) and the unobservable stretches."""
    p = config.true_params
    truth = getattr(H, "params_true", None)
    m_true, com_true = (p.m, np.array([p.dx, p.dy])) if truth is None else (truth[:, 0], truth[:, 1:3])
    t = np.arange(H.phi_hat.shape[0]) * config.dt
    m = H.phi_hat[:, 0]
    m_safe = np.where(np.abs(m) > 1e-9, m, np.nan)
    com = H.phi_hat[:, 1:3] / m_safe[:, None]
    return dict(
        **estimation_errors(t, m, com, m_true, com_true, after),
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
