"""Contacts on the cart's handle: grasp maps, multi-arm wrench allocation, contact placement, excitation.

>>> from wholebody.contacts import HandleSegment, allocate
>>> h = HandleSegment.default()
>>> res = allocate([40.0, 0.0, -2.0], [h.point(0.1), h.point(0.4)])   # two arms, paper eq. (25)
"""

from __future__ import annotations

from wholebody.contacts.allocation import (
    AllocationResult,
    ArmLimits,
    EffortWeights,
    GraspModel,
    WrenchAllocator,
    allocate,
)
from wholebody.contacts.excitation import (
    ContactSchedule,
    InputModel,
    PushSamples,
    SchedulePlan,
    WrenchNoise,
    com_covariance,
    com_crlb_course,
    excitation_score,
    fisher_information,
    input_model,
    objective_value,
    plan_contact_schedule,
    sample_push,
    schedule_com_std,
    schedule_points,
    schedule_score,
)
from wholebody.contacts.handle import (
    ContactSpec,
    HandleSegment,
    cart_wrench,
    grasp_map,
    grasp_map_paper,
    grasp_matrices,
    grasp_matrix,
    wrench_basis,
    wrench_to_b,
)
from wholebody.contacts.placement import ContactPlan, EffortSweep, effort_profile, effort_sweep, optimal_contact_points

__all__ = [
    "AllocationResult",
    "ArmLimits",
    "ContactPlan",
    "ContactSchedule",
    "ContactSpec",
    "EffortSweep",
    "EffortWeights",
    "GraspModel",
    "HandleSegment",
    "InputModel",
    "PushSamples",
    "SchedulePlan",
    "WrenchAllocator",
    "WrenchNoise",
    "allocate",
    "cart_wrench",
    "com_covariance",
    "com_crlb_course",
    "effort_profile",
    "effort_sweep",
    "excitation_score",
    "fisher_information",
    "grasp_map",
    "grasp_map_paper",
    "grasp_matrices",
    "grasp_matrix",
    "input_model",
    "objective_value",
    "optimal_contact_points",
    "plan_contact_schedule",
    "sample_push",
    "schedule_com_std",
    "schedule_points",
    "schedule_score",
    "wrench_basis",
    "wrench_to_b",
]
