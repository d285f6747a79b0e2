"""The seam between the push controller and what it drives: measurements in, commands out.

A :class:`Plant` is whatever answers a :class:`~wholebody.push.controller.PushController`: real robots,
the kinematic plant (ideal joint servos, the exact cart model) or the MuJoCo plant (robots and cart in a
physics engine). Each control period the loop does ``m = plant.measure()`` ->
``cmds = controller.step(m)`` -> ``plant.step(cmds)``.

Conventions: planar poses ``(x, y, yaw)`` in the world {s}; body twists ``(vx, vy, wz)`` in the base
frame; wrenches ``[f, n]`` (6,). A hand wrench is the wrench the hand applies *to the cart*, world-aligned,
about the grasp point. An F/T reading is what the sensor reports: the same wrench, in the sensor frame,
about the sensor origin, with the sensor's noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol
from collections.abc import Sequence

import numpy as np


@dataclass(frozen=True)
class RobotReading:
    """What one mobile manipulator reports at a control instant."""

    #: (3,) base pose in the world (localization / odometry)
    base_pose: np.ndarray
    #: (3,) measured base body twist (vx, vy, wz)
    base_twist: np.ndarray
    #: (n_arm,) arm joint positions (rad), base to tip
    q_arm: np.ndarray
    #: (n_arm,) arm joint velocities (rad/s)
    v_arm: np.ndarray
    #: (6,) F/T reading [force, torque] in the sensor frame at its origin (the wrench on the cart)
    ft: np.ndarray


@dataclass(frozen=True)
class Measurement:
    """Everything the controller may read at time ``t``: motion capture of the cart and the robots' sensors."""

    t: float
    #: (3,) cart pose (x, y, theta) from motion capture
    cart_pose: np.ndarray
    #: (3,) cart velocity (xdot, ydot, thetadot) in the world, from motion capture
    cart_velocity: np.ndarray
    robots: tuple[RobotReading, ...]

    @property
    def z(self) -> np.ndarray:
        """Return the cart measurement vector (x, y, theta, xdot, ydot, thetadot) of the EKF (paper eq. 18)."""
        return np.concatenate((self.cart_pose, self.cart_velocity))


@dataclass(frozen=True)
class RobotCommand:
    """What one mobile manipulator takes for the next control period."""

    #: (n_arm,) arm joint-velocity setpoint (rad/s)
    arm_velocity: np.ndarray
    #: (n_arm,) arm joint-position setpoint at the end of the period (rad): the plan the velocities integrate to
    arm_position: np.ndarray
    #: (n_arm,) arm joint torque (N m): the arm's bias forces (Pinocchio RNEA) + J^T w of the hand wrench
    arm_torque: np.ndarray
    #: (3,) base body-twist setpoint (vx, vy, wz); vy = 0 for a differential drive
    base_twist: np.ndarray
    #: (n_wheels,) wheel-speed setpoints equivalent to `base_twist` (rad/s), in the profile's wheel order
    wheel_rates: np.ndarray
    #: (6,) the allocated wrench the hand should apply to the cart: [f, n] world-aligned at the grasp point
    hand_wrench: np.ndarray
    #: (4, 4) the hand's target pose in the world (the handle point it should hold)
    hand_target: np.ndarray = field(default_factory=lambda: np.eye(4))
    #: (6,) the hand's predicted acceleration over the period: the grasp point's linear acceleration and the hand's
    #: angular acceleration, world-aligned (m/s^2, rad/s^2; the handle's, which the held hand moves with), one row per
    #: hand as `hand_wrench`. A torque-controlled arm adds its own inertia under it to the push
    #: (`arm_control.hand_inertia_torque`); None: not predicted (the kinematic plant's servos need none)
    hand_acceleration: np.ndarray | None = None
    #: (3,) the base's predicted acceleration over the period: (xddot, yddot, yaw ddot) of its planar pose in the world
    #: (m/s^2, rad/s^2); None: not predicted (with a `hand_acceleration`: zero)
    base_acceleration: np.ndarray | None = None


class Plant(Protocol):
    """Robots and cart that answer a push controller, one control period at a time."""

    #: control period (s)
    dt: float

    def measure(self) -> Measurement:
        """Return the sensors' readings at the current instant."""

    def step(self, commands: Sequence[RobotCommand]) -> None:
        """Apply one command per robot for one control period and advance time by `dt`."""


class SimulatedPlant(Plant, Protocol):
    """A plant that also knows the truth a run is judged against (a simulation; real robots do not)."""

    def cart_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the true cart pose and velocity."""

    def cart_wrench(self, commands: Sequence[RobotCommand]) -> np.ndarray:
        """Return the Gamma_MM the hands apply to the cart under `commands`."""

    def robot_states(self) -> list[np.ndarray]:
        """Return the true robot states x = [base pose, arm joints]."""
