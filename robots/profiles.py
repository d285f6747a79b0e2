"""What generic code needs to know about each shipped robot, looked up by name.

A :class:`RobotProfile` names the arm and wheel joints (in the order of the
whole-body vectors), the base type with its geometry, the frames of the grasp
and the F/T sensor, and the arm posture that seeds the grasp IK when the robot
pushes the cart. `wholebody` builds its models from these; it never switches on
a robot's name.

>>> from robots.profiles import profile
>>> profile("ridgeback_iiwa").base
'omnidirectional'
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from robots.errors import UnknownRobotError
from robots.ridgeback_iiwa import RIDGEBACK_WHEEL_RADIUS, RIDGEBACK_WHEEL_X, RIDGEBACK_WHEEL_Y
from robots.wmra import WMRA_TRACK, WMRA_WHEEL_ACCELERATION, WMRA_WHEEL_RADIUS, WMRA_WHEEL_VELOCITY

#: Base kinematics: a differential drive (track and wheel radius read off the model) or a
#: holonomic base with mecanum wheels (radius and wheel positions given here).
BaseType = Literal["differential", "omnidirectional", "none"]


@dataclass(frozen=True)
class RobotProfile:
    """One robot's joints, base, frames and pushing posture (every number sourced in robots/README.md)."""

    name: str
    arm_joints: tuple[str, ...] = ()
    wheel_joints: tuple[str, ...] = ()
    base: BaseType = "none"
    #: Omnidirectional bases: wheel radius (m) and wheel (x, y) in the base frame, in `wheel_joints` order.
    wheel_radius: float | None = None
    wheel_positions: tuple[tuple[float, float], ...] = ()
    #: Frame roles of `robots.load(name)`: the grasp (end effector) and the F/T sensor (None: no sensor).
    ee_frame: str = "ee"
    ft_frame: str | None = None
    #: Arm posture holding the cart's handle with the base behind it (the grasp IK's seed), None if it never pushes.
    push_arm_seed: tuple[float, ...] | None = None
    #: Grasp pitch (rad about y_b): the tool points forward and this much down onto the handle bar.
    grasp_pitch: float = 0.8
    #: Where the base stands while pushing, in the cart frame {b}: x relative to the handle (m, negative =
    #: behind it) and y (m; None = behind the contact point, which only a holonomic base can follow sideways).
    push_base_x: float = -0.65
    push_base_y: float | None = None
    #: Contact point y (m) on the handle when the contact is fixed and none is given.
    push_contact_y: float = -0.2
    #: Base body-twist limits (vx m/s, vy m/s, wz rad/s); vy = 0 for a nonholonomic base.
    base_twist_limit: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Wheel angular acceleration limit (rad/s^2), None = not enforced.
    wheel_acceleration_limit: float | None = None
    #: Look-ahead distance (m) of the base tracker of a nonholonomic base (paper 2 section VI); 0 = pose tracking.
    base_lookahead: float = 0.0

    @property
    def is_mobile_manipulator(self) -> bool:
        """Return True when the robot has an arm on a wheeled base (a `wholebody.WholeBody` can be built)."""
        return bool(self.arm_joints) and self.base != "none"

    @property
    def base_input(self) -> str:
        """Return the whole-body base input: a body twist for a holonomic base, wheel rates for a differential
        drive (its lateral velocity is then zero by construction, paper 2 eq. 11-21)."""
        return "twist" if self.base == "omnidirectional" else "wheels"


WMRA = RobotProfile(
    name="wmra",
    arm_joints=tuple(f"arm_joint{i}" for i in range(1, 8)),
    wheel_joints=("wheel_left_joint", "wheel_right_joint"),
    base="differential",
    # F/T sensing at the wrist: the sensor frame is the end effector (D-H frame 7)
    ft_frame="ee",
    # found by IK (continuation along the handle) with the base axle 1.0 m behind the handle, centred;
    # joint-limit margin 0.4 rad at y = 0
    push_arm_seed=(1.08, 1.54, 1.08, 1.55, 0.53, 0.86, -0.67),
    grasp_pitch=0.2,
    push_base_x=-0.9,
    push_base_y=0.0,
    push_contact_y=0.1,
    base_twist_limit=(
        WMRA_WHEEL_RADIUS * WMRA_WHEEL_VELOCITY,
        0.0,
        2.0 * WMRA_WHEEL_RADIUS * WMRA_WHEEL_VELOCITY / WMRA_TRACK,
    ),
    wheel_acceleration_limit=WMRA_WHEEL_ACCELERATION,
    base_lookahead=0.3,
)

RIDGEBACK_IIWA = RobotProfile(
    name="ridgeback_iiwa",
    arm_joints=tuple(f"iiwa_joint_{i}" for i in range(1, 8)),
    wheel_joints=tuple(f"{a}_{b}_wheel_joint" for a in ("front", "rear") for b in ("left", "right")),
    base="omnidirectional",
    wheel_radius=RIDGEBACK_WHEEL_RADIUS,
    wheel_positions=tuple((sx * RIDGEBACK_WHEEL_X, sy * RIDGEBACK_WHEEL_Y) for sx in (1, -1) for sy in (1, -1)),
    ft_frame="ft_sensor",
    # found by IK with the base 0.65 m behind the handle point; joint-limit margin 1.1 rad
    push_arm_seed=(-1.70, -0.94, 0.28, 1.00, -0.43, -0.47, 0.25),
    base_twist_limit=(1.1, 1.1, 2.0),
)

SHOPPING_CART = RobotProfile(name="shopping_cart")

PROFILES = {p.name: p for p in (RIDGEBACK_IIWA, SHOPPING_CART, WMRA)}


def profile(name: str) -> RobotProfile:
    """Return the profile of a shipped robot; raise `UnknownRobotError` naming the known ones."""
    try:
        return PROFILES[name]
    except KeyError:
        raise UnknownRobotError(f"no profile for robot {name!r}; known: {', '.join(sorted(PROFILES))}") from None


def mobile_manipulators() -> tuple[str, ...]:
    """Return the names of the robots with an arm on a wheeled base."""
    return tuple(sorted(n for n, p in PROFILES.items() if p.is_mobile_manipulator))
