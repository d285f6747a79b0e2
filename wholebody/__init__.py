"""The robot side of cartpush: motion, contacts, the closed push loop, Meshcat scenes, the CLI.

Subpackages (the folder list is the architecture):

* `wholebody.motion`: bases, whole-body kinematics, the QP controller, time parameterization;
* `wholebody.contacts`: the handle and its grasp maps, wrench allocation, contact placement, excitation;
* `wholebody.push`: the closed robot + cart + EKF loop and its reports;
* `wholebody.viz`: Meshcat scenes;


The names below are loaded on first use (``import wholebody`` stays cheap for the CLI):

>>> from wholebody import allocate, HandleSegment, run_push, PushConfig   # doctest: +SKIP
"""

from __future__ import annotations

import importlib
from typing import Any

from wholebody.errors import (
    InfeasibleWrenchError,
    SceneError,
    SingularConfigurationError,
    TrajectoryInfeasibleError,
    WholeBodyError,
)

#: public name -> subpackage that defines it
_LAZY = {
    **{
        n: "wholebody.motion"
        for n in (
            "ControllerConfig",
            "DifferentialDrive",
            "MobileBase",
            "Omnidirectional",
            "ResolvedRateController",
            "SafetyBand",
            "StepResult",
            "WholeBody",
            "ee_path_time_optimal",
            "time_optimal",
            "wholebody_for",
        )
    },
    **{
        n: "wholebody.contacts"
        for n in (
            "AllocationResult",
            "ArmLimits",
            "ContactPlan",
            "EffortSweep",
            "EffortWeights",
            "GraspModel",
            "HandleSegment",
            "WrenchAllocator",
            "allocate",
            "cart_wrench",
            "effort_sweep",
            "grasp_map",
            "grasp_matrices",
            "optimal_contact_points",
            "plan_contact_schedule",
        )
    },
    **{n: "wholebody.push" for n in ("PushConfig", "PushMetrics", "PushResult", "run_demo", "run_push")},
    **{n: "wholebody.viz" for n in ("Scene",)},
}

__all__ = [
    "AllocationResult",
    "ArmLimits",
    "ContactPlan",
    "EffortSweep",
    "ControllerConfig",
    "DifferentialDrive",
    "EffortWeights",
    "GraspModel",
    "HandleSegment",
    "InfeasibleWrenchError",
    "MobileBase",
    "Omnidirectional",
    "PushConfig",
    "PushMetrics",
    "PushResult",
    "ResolvedRateController",
    "SafetyBand",
    "Scene",
    "SceneError",
    "SingularConfigurationError",
    "StepResult",
    "TrajectoryInfeasibleError",
    "WholeBody",
    "WholeBodyError",
    "WrenchAllocator",
    "allocate",
    "cart_wrench",
    "ee_path_time_optimal",
    "effort_sweep",
    "grasp_map",
    "grasp_matrices",
    "optimal_contact_points",
    "plan_contact_schedule",
    "run_demo",
    "run_push",
    "time_optimal",
    "wholebody_for",
]


def __getattr__(name: str) -> Any:
    """Import the subpackage that defines `name` on first use (PEP 562)."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'wholebody' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
