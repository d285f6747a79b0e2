"""Motion of a wheeled mobile manipulator: bases, whole-body kinematics, the QP controller, time parameterization.

The controller's QP is composed of `Task`s (`wholebody.motion.tasks`) and `Limit`s (`wholebody.motion.limits`),
stacked by `solve_step` (`wholebody.motion.qp`).

>>> import robots
>>> from wholebody.motion import wholebody_for, ResolvedRateController
>>> wb = wholebody_for(robots.load("wmra"))
>>> wb.n_u
9
"""

from __future__ import annotations

from wholebody.motion.bases import (
    DifferentialDrive,
    MobileBase,
    Omnidirectional,
    integrate_body_displacement,
    planar_pose_matrix,
    se2_exp_factors,
)
from wholebody.motion.control import (
    ControllerConfig,
    ResolvedRateController,
    SafetyBand,
    StepResult,
    default_limits,
    default_tasks,
    manipulability,
    manipulability_gradient,
    pose_error,
)
from wholebody.motion.kinematics import BaseInput, WholeBody, base_for, wholebody_for
from wholebody.motion.limits import (
    JointPositionLimit,
    JointVelocityLimit,
    SafetyBandLimit,
    WheelAccelerationLimit,
    WheelVelocityLimit,
)
from wholebody.motion.qp import Limit, QPSolution, QPWorkspace, SolverChoice, StepState, Task, solve_step
from wholebody.qp import ProxQPSolver
from wholebody.motion.tasks import BaseTask, DampingTask, EndEffectorTask, ManipulabilityTask, PostureTask
from wholebody.motion.timing import (
    EndEffectorTiming,
    SampledTrajectory,
    ee_path_time_optimal,
    path_parameter,
    time_optimal,
    uniform_scaling_duration,
)

__all__ = [
    "BaseInput",
    "BaseTask",
    "ControllerConfig",
    "DampingTask",
    "DifferentialDrive",
    "EndEffectorTask",
    "EndEffectorTiming",
    "JointPositionLimit",
    "JointVelocityLimit",
    "Limit",
    "ManipulabilityTask",
    "MobileBase",
    "Omnidirectional",
    "PostureTask",
    "ProxQPSolver",
    "QPSolution",
    "QPWorkspace",
    "ResolvedRateController",
    "SafetyBand",
    "SafetyBandLimit",
    "SampledTrajectory",
    "SolverChoice",
    "StepResult",
    "StepState",
    "Task",
    "WheelAccelerationLimit",
    "WheelVelocityLimit",
    "WholeBody",
    "base_for",
    "default_limits",
    "default_tasks",
    "ee_path_time_optimal",
    "integrate_body_displacement",
    "manipulability",
    "manipulability_gradient",
    "path_parameter",
    "planar_pose_matrix",
    "pose_error",
    "se2_exp_factors",
    "solve_step",
    "time_optimal",
    "uniform_scaling_duration",
    "wholebody_for",
]
