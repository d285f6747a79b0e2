"""Settings of the base plan (`wholebody.push.base_plan`), apart so that `wholebody.push.config` can name them."""

from __future__ import annotations

import math
from dataclasses import dataclass

from wholebody.errors import WholeBodyError


@dataclass(frozen=True)
class BasePlanSettings:
    """Knots, margins and weights of the base plan (module docstring)."""

    #: knot spacing (s)
    step: float = 0.1
    #: share of each wheel's URDF speed limit the plan may use
    speed_margin: float = 1.0
    #: seconds the plan starts before and ends after the stretch where the rigid place breaks the wheel limit
    lead: float = 1.0
    tail: float = 3.0
    #: a nonholonomic base's plan also starts where the rigid place moves it along a blocked twist (a differential
    #: drive's sideways) faster than this (m/s; rad/s for a blocked yaw)
    lateral_tolerance: float = 1e-3
    #: closest horizontal mount-wrist distance, as a share of the grasp's nominal one (the arm folds)
    min_reach_fraction: float = 0.6
    #: largest angle between the base's heading and its mount-wrist direction (rad)
    max_reach_angle: float = math.pi / 2
    #: how far (m) the base's footprint may come past the handle's x in {b}; None: not bounded (on Traj. 2 the
    #: plan then puts the Ridgeback's front 0.27 m past the default cart's handle: under its back, which the
    #: MuJoCo plant does not collide)
    front_reach: float | None = None
    weight_acceleration: float = 1e-5
    #: weight (against the hand task's 1) and rate (1/s) of the whole-body QP's pull of the base to its place (the
    #: plan's in a window, the rigid one outside: all through the run, `PushController._follow_plan`), and weight
    #: of its pull of the arm to the plan's postures (in the windows)
    base_weight: float = 0.1
    base_gain: float = 10.0
    posture_weight: float = 0.1
    #: SLSQP iterations per window: the plan's reach (rho) is at its optimum by 40 on Traj. 2 (0.7114 m in each of its
    #: three windows, as after 300); the rest only smooths the path (weight_acceleration), at 0.05 s CPU each
    max_iterations: int = 40
    #: the arm's elbow kept this far (rad) from straight on its bent side (`base_plan.guard_elbow`); None: off
    elbow_guard: float | None = 0.3

    def __post_init__(self) -> None:
        if not (self.step > 0 and 0 < self.speed_margin <= 1 and self.lead >= 2 * self.step and self.tail >= 0):
            raise WholeBodyError("base plan: step > 0, speed_margin in (0, 1], lead >= 2 step, tail >= 0")
