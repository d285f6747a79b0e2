"""Motion of a wheeled mobile manipulator: bases, whole-body kinematics, the QP controller, time parameterization.

>>> import robots
>>> from wholebody.motion import wholebody_for, ResolvedRateController
>>> wb = wholebody_for(robots.load("wmra"))
>>> wb.n_u
9
"""
from __future__ import annotations

from wholebody.motion.bases import (DifferentialDrive, MobileBase, Omnidirectional, integrate_body_displacement,
                                    planar_pose_matrix, se2_exp_factors)
from wholebody.motion.control import (ControllerConfig, ResolvedRateController, SafetyBand, StepResult,
                                      manipulability, manipulability_gradient, pose_error)
from wholebody.motion.kinematics import BaseInput, WholeBody, base_for, wholebody_for
from wholebody.motion.timing import (EndEffectorTiming, SampledTrajectory, ee_path_time_optimal, path_parameter,
                                     time_optimal, uniform_scaling_duration)

__all__ = [
    "BaseInput", "ControllerConfig", "DifferentialDrive", "EndEffectorTiming", "MobileBase", "Omnidirectional",
    "ResolvedRateController", "SafetyBand", "SampledTrajectory", "StepResult", "WholeBody", "base_for",
    "ee_path_time_optimal", "integrate_body_displacement", "manipulability", "manipulability_gradient",
    "path_parameter", "planar_pose_matrix", "pose_error", "se2_exp_factors", "time_optimal", "uniform_scaling_duration", "wholebody_for",
]
