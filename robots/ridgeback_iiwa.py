"""Clearpath Ridgeback + KUKA LBR iiwa 14 R820 + Robotiq FT-300 and 2F-85: the cart paper's robot.

Numbers come from robots/README.md (Drake's iiwa14 URDF, the ridgeback
description and control.yaml, Robotiq manuals); primitives stand in for meshes.
"""

from __future__ import annotations

import math

from robots.urdf_text import Inertial, Shape, box_inertial, cylinder_inertial, joint, link, robot

PI = math.pi

#: Ridgeback (ridgeback.urdf.xacro, control.yaml).
RIDGEBACK_WHEEL_RADIUS = 0.0759
RIDGEBACK_WHEEL_WIDTH = 0.079
RIDGEBACK_WHEEL_MASS = 2.3
RIDGEBACK_WHEEL_X = 0.638 / 2  # wheelbase 0.638 m
RIDGEBACK_WHEEL_Y = 0.551 / 2  # track 0.551 m
RIDGEBACK_WHEEL_Z = 0.05  # wheel centres in base_link
RIDGEBACK_CHASSIS = (0.960, 0.793, 0.216)
RIDGEBACK_CHASSIS_MASS = 165.304
RIDGEBACK_ROCKER_MASS = 10.267
RIDGEBACK_MID_MOUNT_Z = 0.28
RIDGEBACK_MAX_SPEED = 1.1  # m/s, x and y
RIDGEBACK_MAX_YAW_RATE = 2.0  # rad/s
#: HAMS mount of the iiwa (ridgeback_manipulation): from mid_mount, yaw -pi/2.
IIWA_MOUNT_XYZ = (-0.27913, 0.0, 0.445)
IIWA_MOUNT_YAW = -PI / 2

#: iiwa 14 joints (Drake iiwa14_no_collision.urdf): parent->joint xyz, rpy, limit deg, vel rad/s, effort N m.
IIWA_JOINTS = (
    ((0, 0, 0.1575), (0, 0, 0), 170, 1.4835, 320),
    ((0, 0, 0.2025), (PI / 2, 0, PI), 120, 1.4835, 320),
    ((0, 0.2045, 0), (PI / 2, 0, PI), 170, 1.7453, 176),
    ((0, 0, 0.2155), (PI / 2, 0, 0), 120, 1.3090, 176),
    ((0, 0.1845, 0), (-PI / 2, PI, 0), 170, 2.2689, 110),
    ((0, 0, 0.2155), (PI / 2, 0, 0), 120, 2.3562, 40),
    ((0, 0.081, 0), (-PI / 2, PI, 0), 175, 2.3562, 40),
)
IIWA_FLANGE_Z = 0.045
IIWA_DAMPING = 0.5
#: Drake inertials of iiwa_link_0..7: mass, COM, (Ixx, Iyy, Izz) about the COM.
IIWA_INERTIALS = (
    (5.0, (-0.1, 0, 0.07), (0.05, 0.06, 0.03)),
    (5.76, (0, -0.03, 0.12), (0.033, 0.0333, 0.0123)),
    (6.35, (0.0003, 0.059, 0.042), (0.0305, 0.0304, 0.011)),
    (3.5, (0, 0.03, 0.13), (0.025, 0.0238, 0.0076)),
    (3.5, (0, 0.067, 0.034), (0.017, 0.0164, 0.006)),
    (3.5, (0.0001, 0.021, 0.076), (0.01, 0.0087, 0.00449)),
    (1.8, (0, 0.0006, 0.0004), (0.0049, 0.0047, 0.0036)),
    (1.2, (0, 0, 0.02), (0.001, 0.001, 0.001)),
)
#: Robotiq FT-300: 0.300 kg, COM 17 mm, 37.5 mm thick, measurement frame 16.25 mm from the robot side.
FT300_MASS, FT300_COM_Z, FT300_THICKNESS, FT300_MEASURE_Z = 0.300, 0.017, 0.0375, 0.01625
#: Robotiq 2F-85: about 0.905 kg (FT300+2F-85 = 1.205 kg, COM 76 mm); fingertip pad centre 0.149 m from its base.
GRIPPER_MASS = 0.905
GRIPPER_COM_Z = (1.205 * 0.076 - FT300_MASS * FT300_COM_Z) / GRIPPER_MASS - FT300_THICKNESS
GRIPPER_LENGTH = 0.149


def _segment(p: tuple[float, float, float], radius: float) -> Shape | None:
    """Return a cylinder from the link origin to `p` (p along z or y only)."""
    x, y, z = p
    if abs(z) > 1e-9 and abs(x) < 1e-9 and abs(y) < 1e-9:
        return Shape("cylinder", (radius, abs(z)), (0, 0, z / 2), material="orange")
    if abs(y) > 1e-9 and abs(x) < 1e-9 and abs(z) < 1e-9:
        return Shape("cylinder", (radius, abs(y)), (0, y / 2, 0), (-PI / 2, 0, 0), material="orange")
    return None


def _chassis() -> list[str]:
    """Return the floor link `base_footprint` and the Ridgeback body `base_link` (chassis and mid-mount plate)."""
    cx, cy, cz = RIDGEBACK_CHASSIS
    chassis_center_z = 0.018 - (RIDGEBACK_WHEEL_RADIUS - RIDGEBACK_WHEEL_Z) + cz / 2
    shapes = (
        Shape("box", RIDGEBACK_CHASSIS, (0, 0, chassis_center_z), material="yellow"),
        Shape("box", (cx * 0.98, cy * 0.98, 0.01), (0, 0, RIDGEBACK_MID_MOUNT_Z - 0.005), material="dark"),
    )
    return [
        link("base_footprint"),
        link(
            "base_link", box_inertial(RIDGEBACK_CHASSIS_MASS, RIDGEBACK_CHASSIS, com=(0, 0, chassis_center_z)), shapes
        ),
        joint(
            "base_joint", "fixed", "base_footprint", "base_link", xyz=(0, 0, RIDGEBACK_WHEEL_RADIUS - RIDGEBACK_WHEEL_Z)
        ),
    ]


def _rockers() -> list[str]:
    """Return the front and rear rocker links, fixed to `base_link` over the wheel axles."""
    parts: list[str] = []
    for name, sx in (("front", 1.0), ("rear", -1.0)):
        parts.append(
            link(
                f"{name}_rocker",
                box_inertial(RIDGEBACK_ROCKER_MASS, (0.08, 0.6, 0.06)),
                (Shape("box", (0.08, 0.6, 0.06), material="dark"),),
            )
        )
        parts.append(
            joint(
                f"{name}_rocker_joint",
                "fixed",
                "base_link",
                f"{name}_rocker",
                xyz=(sx * RIDGEBACK_WHEEL_X, 0, RIDGEBACK_WHEEL_Z),
            )
        )
    return parts


def _wheels() -> list[str]:
    """Return the four mecanum wheels (as plain cylinders) on continuous joints to `base_link`."""
    parts: list[str] = []
    for fx, sx in (("front", 1.0), ("rear", -1.0)):
        for side, sy in (("left", 1.0), ("right", -1.0)):
            w = f"{fx}_{side}_wheel"
            parts.append(
                link(
                    w,
                    cylinder_inertial(RIDGEBACK_WHEEL_MASS, RIDGEBACK_WHEEL_RADIUS, RIDGEBACK_WHEEL_WIDTH),
                    (Shape("cylinder", (RIDGEBACK_WHEEL_RADIUS, RIDGEBACK_WHEEL_WIDTH), material="dark"),),
                )
            )
            parts.append(
                joint(
                    f"{w}_joint",
                    "continuous",
                    "base_link",
                    w,
                    xyz=(sx * RIDGEBACK_WHEEL_X, sy * RIDGEBACK_WHEEL_Y, RIDGEBACK_WHEEL_Z),
                    rpy=(-PI / 2, 0, 0),
                    limit=(0, 0, 50.0, RIDGEBACK_MAX_SPEED / RIDGEBACK_WHEEL_RADIUS),
                )
            )
    return parts


def _arm_mount() -> list[str]:
    """Return `mid_mount` and the HAMS pedestal `arm_mount_link` the iiwa stands on."""
    mx, my, mz = IIWA_MOUNT_XYZ
    return [
        link("mid_mount"),
        joint("mid_mount_joint", "fixed", "base_link", "mid_mount", xyz=(0, 0, RIDGEBACK_MID_MOUNT_Z)),
        link("arm_mount_link", None, (Shape("box", (0.3, 0.3, mz), (0, 0, -mz / 2), material="grey"),)),
        joint(
            "arm_mount_joint", "fixed", "mid_mount", "arm_mount_link", xyz=IIWA_MOUNT_XYZ, rpy=(0, 0, IIWA_MOUNT_YAW)
        ),
    ]


def _iiwa_link(i: int) -> list[str]:
    """Return iiwa link i (1..7) and its revolute joint to link i-1 (Drake's numbers)."""
    xyz, rpy, lim_deg, vel, effort = IIWA_JOINTS[i - 1]
    nxt = IIWA_JOINTS[i][0] if i < 7 else (0, 0, IIWA_FLANGE_Z)
    shapes = [Shape("sphere", (0.075,), material="orange")]
    seg = _segment(nxt, 0.065)
    if seg is not None:
        shapes.append(seg)
    return [
        link(f"iiwa_link_{i}", _inertial(i), tuple(shapes)),
        joint(
            f"iiwa_joint_{i}",
            "revolute",
            f"iiwa_link_{i - 1}",
            f"iiwa_link_{i}",
            xyz=xyz,
            rpy=rpy,
            limit=(-math.radians(lim_deg), math.radians(lim_deg), effort, vel),
            damping=IIWA_DAMPING,
        ),
    ]


def _iiwa() -> list[str]:
    """Return the iiwa 14 on `arm_mount_link`: base link 0, links 1..7 and the `iiwa_flange` frame."""
    parts = [
        link("iiwa_link_0", _inertial(0), (Shape("cylinder", (0.1, 0.1575), (0, 0, 0.1575 / 2), material="grey"),)),
        joint("iiwa_base_joint", "fixed", "arm_mount_link", "iiwa_link_0"),
    ]
    for i in range(1, len(IIWA_JOINTS) + 1):
        parts.extend(_iiwa_link(i))
    parts.append(link("iiwa_flange"))
    parts.append(joint("iiwa_flange_joint", "fixed", "iiwa_link_7", "iiwa_flange", xyz=(0, 0, IIWA_FLANGE_Z)))
    return parts


def _tool() -> list[str]:
    """Return the FT-300 (with its measurement frame `ft_sensor`), the 2F-85 gripper and the grasp frame `ee`."""
    return [
        link(
            "ft300",
            cylinder_inertial(FT300_MASS, 0.0375, FT300_THICKNESS, com=(0, 0, FT300_COM_Z)),
            (Shape("cylinder", (0.0375, FT300_THICKNESS), (0, 0, FT300_THICKNESS / 2), material="dark"),),
        ),
        joint("ft300_joint", "fixed", "iiwa_flange", "ft300"),
        link("ft_sensor"),
        joint("ft_sensor_joint", "fixed", "ft300", "ft_sensor", xyz=(0, 0, FT300_MEASURE_Z)),
        link(
            "gripper",
            box_inertial(GRIPPER_MASS, (0.09, 0.06, 0.12), com=(0, 0, GRIPPER_COM_Z)),
            (
                Shape("box", (0.09, 0.06, 0.1), (0, 0, 0.05), material="dark"),
                Shape("box", (0.02, 0.025, 0.05), (0.03, 0, 0.125), material="silver"),
                Shape("box", (0.02, 0.025, 0.05), (-0.03, 0, 0.125), material="silver"),
            ),
        ),
        joint("gripper_joint", "fixed", "ft300", "gripper", xyz=(0, 0, FT300_THICKNESS)),
        link("ee"),
        joint("ee_joint", "fixed", "gripper", "ee", xyz=(0, 0, GRIPPER_LENGTH)),
    ]


def ridgeback_iiwa_urdf() -> str:
    """Return the URDF text of the Ridgeback + iiwa 14 + FT-300 + 2F-85 mobile manipulator.

    Root link `base_footprint` on the floor (`robots.load` adds the planar joint);
    `base_link` 0.0259 m above it; frames `ft_sensor` (FT-300 measurement frame)
    and `ee` (grasp point between the fingertip pads, z along the tool axis).
    """
    parts = _chassis() + _rockers() + _wheels() + _arm_mount() + _iiwa() + _tool()
    return robot("ridgeback_iiwa", "".join(parts))


def _inertial(i: int) -> Inertial:
    mass, com, (ixx, iyy, izz) = IIWA_INERTIALS[i]
    return Inertial(mass, com, ixx, iyy, izz)
