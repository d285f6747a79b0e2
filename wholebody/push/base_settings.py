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
    #: of its pull of the arm to the plan's postures (in the windows). The base's pull is as strong as the hand task:
    #: a held hand does not follow the QP's arm rates, so what the QP trades for them is base motion lost (the
    #: base 2 cm behind its place, the hand 1 cm ahead of its target: the QP's base closes 19 % of the gap at 0.1,
    #: 57 % at 1; tests/wholebody/push/test_base_hold.py's `base_command`). Measured (two Ridgeback + iiwa,
    #: `cartpush push --plant mujoco --arms 2 --trajectory 2 --seed 0 --json`, force loops "full"): at 0.1 robot 0's
    #: base fell 84 mm RMS (255 max) behind its place in the turns (its servos follow the commanded twist within
    #: 0.01 m/s; the command was 0.04-0.08 m/s off the plan's rates), its elbow went through straight to -0.6 rad
    #: (tracking 17.4 mm, wrench error 128 % of the hand force); at 1 the elbows stay above 0.73 rad (2.57 mm,
    #: 27.1 %). One arm, Traj. 2, seeds 0/1/2 (at c50c77c): 4.03/3.93/5.16 -> 3.97/4.06/5.25 mm, wrench error
    #: 2.4/2.8/2.4 -> 2.8/2.9/2.7 %
    base_weight: float = 1.0
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
