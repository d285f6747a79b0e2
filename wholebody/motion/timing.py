"""Time-optimal parameterization of joint paths (and end-effector paths through the IK) with toppra.

The geometric path is the cubic spline (scipy "not-a-knot") through the waypoints,
parameterized by normalised chord length s in [0, 1]; toppra finds the fastest
s(t) from rest to rest under joint velocity and acceleration limits.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from wholebody.motion.control import ControllerConfig, ResolvedRateController
from wholebody.errors import TrajectoryInfeasibleError, WholeBodyError
from wholebody.motion.kinematics import WholeBody


@dataclass(frozen=True)
class SampledTrajectory:
    """A trajectory sampled at times t: positions q, velocities qd, accelerations qdd (rows per sample)."""

    t: np.ndarray = field(repr=False)
    q: np.ndarray = field(repr=False)
    qd: np.ndarray = field(repr=False)
    qdd: np.ndarray = field(repr=False)

    @property
    def duration(self) -> float:
        """Return the trajectory's duration (s)."""
        return float(self.t[-1])


def path_parameter(waypoints: np.ndarray) -> np.ndarray:
    """Return the normalised cumulative chord length s in [0, 1] of the waypoints (N,)."""
    seg = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    if np.any(seg <= 1e-12):
        raise WholeBodyError("consecutive waypoints must differ (a zero-length segment has no direction)")
    s = np.r_[0.0, np.cumsum(seg)]
    return s / s[-1]


def time_optimal(
    waypoints: np.ndarray,
    vel_limits: Sequence[float],
    acc_limits: Sequence[float],
    sample_dt: float = 0.01,
    gridpoints: int | None = None,
    safety_factor: float = 0.98,
) -> SampledTrajectory:
    """Return the time-optimal rest-to-rest trajectory along the spline through `waypoints` (N x n).

    Args:
        waypoints: N >= 2 joint configurations (rows).
        vel_limits, acc_limits: symmetric limits per joint (n,), positive.
        sample_dt: sampling period of the returned trajectory (s); the last sample is at the end.
        gridpoints: number of toppra grid points (default max(400, 4 N)).
        safety_factor: toppra sees limits scaled by this factor: its constraints hold only at the
            grid points, and between them the velocity can exceed by ~0.2 %; the margin makes the
            sampled trajectory respect the true limits.

    Raises:
        TrajectoryInfeasibleError: when toppra finds no feasible parameterization.
    """
    wp = np.asarray(waypoints, dtype=float)
    vmax = np.asarray(vel_limits, dtype=float)
    amax = np.asarray(acc_limits, dtype=float)
    if wp.ndim != 2 or wp.shape[0] < 2:
        raise WholeBodyError(f"waypoints must be an N x n array with N >= 2, got shape {wp.shape}")
    n = wp.shape[1]
    if vmax.shape != (n,) or amax.shape != (n,):
        raise WholeBodyError(f"vel_limits and acc_limits must have {n} entries")
    if not (np.all(vmax > 0) and np.all(amax > 0) and np.all(np.isfinite(wp))):
        raise WholeBodyError("limits must be positive and waypoints finite")
    s = path_parameter(wp)
    import toppra  # here: toppra imports matplotlib.pyplot (about 1 s), which no push needs
    import toppra.algorithm
    import toppra.constraint

    path = toppra.SplineInterpolator(s, wp)
    if not 0 < safety_factor <= 1:
        raise WholeBodyError("safety_factor must be in (0, 1]")
    v, a = safety_factor * vmax, safety_factor * amax
    pc_vel = toppra.constraint.JointVelocityConstraint(np.column_stack([-v, v]))
    pc_acc = toppra.constraint.JointAccelerationConstraint(np.column_stack([-a, a]))
    grid = np.linspace(0.0, 1.0, gridpoints or max(400, 4 * len(s)))
    algo = toppra.algorithm.TOPPRA([pc_vel, pc_acc], path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    traj = algo.compute_trajectory(0.0, 0.0)
    if traj is None:  # toppra returns None silently when infeasible
        raise TrajectoryInfeasibleError("toppra found no feasible time parameterization for this path and these limits")
    T = float(traj.duration)
    t = np.r_[np.arange(0.0, T, sample_dt), T]
    return SampledTrajectory(t=t, q=traj(t), qd=traj(t, 1), qdd=traj(t, 2))


def uniform_scaling_duration(
    waypoints: np.ndarray, vel_limits: Sequence[float], acc_limits: Sequence[float], samples: int = 4001
) -> float:
    """Return the shortest duration T of the same spline path timed by s = 3 tau^2 - 2 tau^3, tau = t / T.

    The reference toppra must beat: one fixed rest-to-rest profile uniformly scaled in time
    until the velocity and acceleration limits hold.
    """
    from scipy.interpolate import CubicSpline

    wp = np.asarray(waypoints, dtype=float)
    spl = CubicSpline(path_parameter(wp), wp)
    tau = np.linspace(0.0, 1.0, samples)
    s, s1, s2 = 3 * tau**2 - 2 * tau**3, 6 * tau - 6 * tau**2, 6 - 12 * tau
    d1, d2 = spl(s, 1), spl(s, 2)
    vel = np.abs(d1 * s1[:, None]) / np.asarray(vel_limits)
    acc = np.abs(d2 * (s1**2)[:, None] + d1 * s2[:, None]) / np.asarray(acc_limits)
    return float(max(vel.max(), np.sqrt(acc.max())))


@dataclass(frozen=True)
class EndEffectorTiming:
    """An end-effector path timed through the IK: joint path [arm q, wheel angles] and its trajectory.

    Attributes:
        joint_path: (N x (n_arm + n_wheels)) IK solutions, wheel angles accumulated from 0.
        states: (N x (3 + n_arm)) reduced states [base pose, arm q] of the IK solutions.
        trajectory: the time-optimal trajectory of `joint_path`.
        max_ik_error_m: largest EE position error of the IK solutions.
    """

    joint_path: np.ndarray = field(repr=False)
    states: np.ndarray = field(repr=False)
    trajectory: SampledTrajectory
    max_ik_error_m: float


def ee_path_time_optimal(
    wb: WholeBody,
    x0: Sequence[float],
    ee_waypoints: Sequence[pin.SE3],
    acc_limits: Sequence[float],
    ik_dt: float = 0.01,
    ik_iterations: int = 200,
    ik_tolerance: float = 1e-5,
    sample_dt: float = 0.01,
) -> EndEffectorTiming:
    """Return the time-optimal timing of an EE path: resolved-rate IK to each waypoint, then toppra.

    The joint path is [arm q, cumulative wheel angles] (wheel input only) so that the
    limits are the joints' and wheels' own; re-timing a path keeps its geometry, hence
    the base follows the same (nonholonomic) track.
    """
    if wb.base_input != "wheels":
        raise WholeBodyError("ee_path_time_optimal needs a wheel-rate WholeBody (base_input='wheels')")
    ctrl = ResolvedRateController(wb, ControllerConfig(secondary="posture"))
    x = np.asarray(x0, dtype=float).copy()
    wheels = np.zeros(wb.base.n_wheels)
    rows: list[np.ndarray] = []
    states: list[np.ndarray] = []
    worst = 0.0
    for T_des in ee_waypoints:
        for _ in range(ik_iterations):
            res = ctrl.step(x, T_des, None, ik_dt)
            if res.position_error < ik_tolerance and res.orientation_error < ik_tolerance:
                break
            x = wb.integrate(x, res.u, ik_dt)
            wheels = wheels + wb.wheel_rates(res.u) * ik_dt
        err = float(np.linalg.norm(wb.ee_placement(x).translation - T_des.translation))
        worst = max(worst, err)
        row = np.r_[x[3:], wheels]
        if rows and np.linalg.norm(row - rows[-1]) < 1e-9:
            continue
        rows.append(row)
        states.append(x.copy())
    path = np.asarray(rows)
    vmax = np.r_[wb.arm_velocity_limit, wb.wheel_velocity_limit]
    traj = time_optimal(path, vmax, acc_limits, sample_dt=sample_dt)
    return EndEffectorTiming(joint_path=path, states=np.asarray(states), trajectory=traj, max_ik_error_m=worst)
