"""The §IV tracking task solved by placo's kinematics solver on the same URDF, for comparison.

placo tasks used (placo 0.10.2; the robot is a free-flyer in placo):
- `FrameTask("ee")`, soft, weights 1 (position) / 1 (orientation): the desired pose at t + dt.
- `WheelTask` per driven wheel, hard: WMRA left wheel non-omni (no forward and no lateral slip,
  contact height), right wheel `omniwheel=True` (two non-omni wheels on one axle give duplicate
  lateral rows); Ridgeback: four `omniwheel=True` tasks (placo has no 45-degree mecanum roller, a
  90-degree omniwheel gives the same holonomic base motion but other wheel angles).
  Ridgeback: three of the four are hard, the fourth soft (weight 1e3): four contact heights
  would repeat a row and make placo's equality constraints rank deficient (QPError).
- WMRA: the caster wheels as soft (1e3) omniwheel `WheelTask`s with their swivels masked, so the
  chassis stays level (the drive-wheel contacts alone leave the pitch free on one axle).
  `AxisAlignTask` was tried first: placo 0.10.2 returns "NaN in the QP solution" when the axis is
  already aligned.
- `JointsTask` on the arm joints, soft, weight 1e-3: the same posture pull as our controller.
- joint position and velocity limits enabled; solver.dt = 1/rate.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
import placo

import robots
from wholebody.errors import WholeBodyError
from wholebody.motion.bases import planar_pose_matrix
from wholebody.motion.experiments import TrackingResult, initial_state, path_function, run_tracking
from wholebody.motion.kinematics import WholeBody, wholebody_for


@dataclass(frozen=True)
class PlacoRun:
    """A placo tracking run: errors, states and step times.

    Attributes:
        max_position_error_m, rms_position_error_m, max_orientation_error_rad: EE errors.
        x: reduced states [base x, y, theta, arm q] per sample (steps+1, 3+n_arm).
        step_times_s: wall time of each solve + kinematics update.
    """

    max_position_error_m: float
    rms_position_error_m: float
    max_orientation_error_rad: float
    x: np.ndarray = field(repr=False)
    step_times_s: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class Comparison:
    """Ours vs placo on the same task: errors, trajectory agreement and median step times."""

    robot: str
    path: str
    ours: TrackingResult = field(repr=False)
    placo: PlacoRun = field(repr=False)
    max_arm_joint_difference_rad: float
    max_base_position_difference_m: float
    ours_median_step_us: float
    placo_median_step_us: float

    def summary(self) -> dict:
        """Return the comparison's scalar numbers as a JSON-ready dict."""
        return {
            "robot": self.robot,
            "path": self.path,
            "ours_max_position_error_m": self.ours.max_position_error_m,
            "ours_rms_position_error_m": self.ours.rms_position_error_m,
            "placo_max_position_error_m": self.placo.max_position_error_m,
            "placo_rms_position_error_m": self.placo.rms_position_error_m,
            "placo_max_orientation_error_rad": self.placo.max_orientation_error_rad,
            "max_arm_joint_difference_rad": self.max_arm_joint_difference_rad,
            "max_base_position_difference_m": self.max_base_position_difference_m,
            "ours_median_step_us": self.ours_median_step_us,
            "placo_median_step_us": self.placo_median_step_us,
        }


class PlacoTracker:
    """placo's KinematicsSolver set up for end-effector tracking on a shipped mobile manipulator."""

    def __init__(self, wb: WholeBody, x0: np.ndarray, dt: float, posture_weight: float = 1e-3) -> None:
        self.wb = wb
        self.robot = placo.RobotWrapper(str(wb.robot.urdf), placo.Flags.ignore_collisions)
        name = wb.robot.name
        for j, v in zip(wb.arm_joints, x0[3:]):
            self.robot.set_joint(j, float(v))
        self.robot.set_T_world_fbase(planar_pose_matrix(*x0[:3]))
        self.robot.update_kinematics()
        s = placo.KinematicsSolver(self.robot)
        s.dt = dt
        s.enable_joint_limits(True)
        s.enable_velocity_limits(True)
        for j in self.robot.joint_names():
            if "caster" in j and "swivel" in j:
                s.mask_dof(j)
        T0 = self.robot.get_T_world_frame("ee")
        self.ee_task = s.add_frame_task("ee", T0)
        self.ee_task.configure("ee", "soft", 1.0, 1.0)
        if name == "wmra":
            r = wb.base.wheel_radius
            s.add_wheel_task(wb.wheel_joints[0], r, False).configure("wheel_l", "hard", 1.0)
            s.add_wheel_task(wb.wheel_joints[1], r, True).configure("wheel_r", "hard", 1.0)
            # pitch is free on one axle: the caster wheels touch the floor too (soft omniwheels, swivels
            # masked); an AxisAlignTask returns NaN in placo 0.10.2 when the axes are already aligned
            from robots.wmra import WMRA_CASTER_RADIUS

            for side in ("left", "right"):
                s.add_wheel_task(f"caster_{side}_wheel_joint", WMRA_CASTER_RADIUS, True).configure(
                    f"caster_{side}", "soft", 1e3
                )
        elif name == "ridgeback_iiwa":
            # three hard omniwheels fix height, roll, pitch and the planar motion; a 4th hard one
            # would repeat a height row (rank-deficient equality constraints in placo's QP)
            for k, j in enumerate(wb.wheel_joints):
                s.add_wheel_task(j, wb.base.wheel_radius, True).configure(
                    f"wheel{k}", "hard" if k < 3 else "soft", 1.0 if k < 3 else 1e3
                )
        else:
            raise WholeBodyError(f"no placo setup for robot {name!r}")
        joints = s.add_joints_task()
        joints.set_joints({j: float(v) for j, v in zip(wb.arm_joints, x0[3:])})
        joints.configure("posture", "soft", posture_weight)
        self.solver = s

    def step(self, T_des: pin.SE3) -> float:
        """Solve one step towards T_des and integrate; return the wall time of `step_to` (s)."""
        return self.step_to(T_des.homogeneous)

    def step_to(self, target: np.ndarray) -> float:
        """Assign the 4 x 4 target, solve one step (solve and integrate) and update the kinematics; return the
        wall time of the three (s)."""
        t0 = time.perf_counter()
        self.ee_task.T_world_frame = target
        self.solver.solve(True)
        self.robot.update_kinematics()
        return time.perf_counter() - t0

    def state(self) -> np.ndarray:
        """Return the reduced state [base x, y, theta, arm q] of placo's robot."""
        T = self.robot.get_T_world_fbase()
        th = float(np.arctan2(T[1, 0], T[0, 0]))
        return np.r_[T[0, 3], T[1, 3], th, [self.robot.get_joint(j) for j in self.wb.arm_joints]]

    def ee(self) -> pin.SE3:
        """Return placo's end-effector placement."""
        T = self.robot.get_T_world_frame("ee")
        return pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())


def run_placo(
    robot: str = "wmra", path: str = "line", duration: float = 60.0, rate: float = 100.0, wb: WholeBody | None = None
) -> PlacoRun:
    """Return placo's run of the §IV experiment (same initial state, path and rate as `run_tracking`)."""
    f = path_function(path)
    wb = wb or wholebody_for(robots.load(robot))
    x0 = initial_state(wb)
    dt = 1.0 / rate
    n = int(round(duration * rate))
    tr = PlacoTracker(wb, x0, dt)
    T0 = tr.ee()
    xs = np.empty((n + 1, x0.size))
    pos, rot, times = np.empty(n + 1), np.empty(n + 1), np.empty(n)
    xs[0], pos[0], rot[0] = tr.state(), 0.0, 0.0
    for k in range(1, n + 1):
        T_des = pin.SE3(T0.rotation, T0.translation + f(k * dt)[0])
        times[k - 1] = tr.step(T_des)
        T = tr.ee()
        xs[k] = tr.state()
        pos[k] = np.linalg.norm(T_des.translation - T.translation)
        rot[k] = np.linalg.norm(pin.log3(T_des.rotation @ T.rotation.T))
    return PlacoRun(
        max_position_error_m=float(pos.max()),
        rms_position_error_m=float(np.sqrt(np.mean(pos**2))),
        max_orientation_error_rad=float(rot.max()),
        x=xs,
        step_times_s=times,
    )


def compare(robot: str = "wmra", path: str = "line", duration: float = 60.0, rate: float = 100.0) -> Comparison:
    """Return ours vs placo on the §IV experiment (base free, wheel-rate input for both robots)."""
    wb = wholebody_for(robots.load(robot))
    ours_times: list[float] = []
    from wholebody.motion.control import ResolvedRateController

    original = ResolvedRateController.step

    def timed(self, *a, **k):
        t0 = time.perf_counter()
        out = original(self, *a, **k)
        ours_times.append(time.perf_counter() - t0)
        return out

    ResolvedRateController.step = timed
    try:
        ours = run_tracking(robot, path, duration=duration, rate=rate, wb=wb)
    finally:
        ResolvedRateController.step = original
    pl = run_placo(robot, path, duration, rate, wb=wb)
    dq = np.abs(ours.x[:, 3:] - pl.x[:, 3:]).max()
    dp = np.linalg.norm(ours.x[:, :2] - pl.x[:, :2], axis=1).max()
    return Comparison(
        robot=robot,
        path=path,
        ours=ours,
        placo=pl,
        max_arm_joint_difference_rad=float(dq),
        max_base_position_difference_m=float(dp),
        ours_median_step_us=float(np.median(ours_times) * 1e6),
        placo_median_step_us=float(np.median(pl.step_times_s) * 1e6),
    )
