"""The USF wheelchair-mounted robotic arm (WMRA) as a URDF family (the WMRA paper, docs/papers.md).

The 7-DoF arm follows the paper's modified D-H table (Table I): all a = 0,
alpha_{i-1} alternating -90/+90 deg, offsets d1..d7, theta_i = q_i with no
hidden offsets, so that logged joint angles of the real program map one to one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Sequence

from robots.errors import RobotError
from robots.urdf_text import Shape, box_inertial, cylinder_inertial, joint, link, robot, combine

#: D-H twist alpha_{i-1} of joint i (paper Table I), radians.
WMRA_ALPHA: tuple[float, ...] = tuple(math.radians(a) for a in (-90, 90, -90, 90, -90, 90, -90))

#: "Actual arm" D-H offsets d1..d7 of the USF Master_Program (DH.cpp), metres.
WMRA_D: tuple[float, ...] = (0.102, 0.133, 0.502, 0.090, 0.375, 0.0, 0.304)
#: Wheel track L1, mount offsets (L2, L3, L4) and wheel radius L5 (WCD.cpp active values), metres.
WMRA_TRACK = 0.500
WMRA_MOUNT: tuple[float, float, float] = (0.400, 0.230, 0.200)
WMRA_WHEEL_RADIUS = 0.170

#: Joint limits (Jlimit.cpp), degrees; joint-rate clamp 0.9 rad/s (WMRA-Mod-Program).
WMRA_Q_MIN_DEG = (-170, -45, -170, -170, -170, -79, -200)
WMRA_Q_MAX_DEG = (170, 170, 170, 270, 170, 79, 200)
WMRA_JOINT_VELOCITY = 0.9
#: Estimates (no public source): joint efforts N m, wheel speed rad/s (about 1.5 m/s), wheel effort.
WMRA_JOINT_EFFORT = (60.0, 60.0, 30.0, 30.0, 15.0, 10.0, 10.0)
WMRA_WHEEL_VELOCITY = 8.8
WMRA_WHEEL_EFFORT = 60.0
#: Estimate: drive-wheel angular acceleration limit, rad/s^2 (about 1 m/s^2 at the rim).
WMRA_WHEEL_ACCELERATION = 6.0
#: Estimates: link masses kg (arm about 12 kg), wheelchair chassis mass, wheel and caster sizes.
WMRA_LINK_MASS = (2.0, 2.0, 2.5, 1.5, 1.5, 1.0, 1.0)
WMRA_CHASSIS_MASS = 100.0
WMRA_WHEEL_MASS = 4.0
WMRA_CASTER_X = 0.50
WMRA_CASTER_HALF_TRACK = 0.25
WMRA_CASTER_RADIUS = 0.10


@dataclass(frozen=True)
class WmraBuild:
    """Dimensions of one WMRA build: D-H offsets d1..d7, track L1, mount (L2, L3, L4), wheel radius L5 (m)."""

    d: tuple[float, ...] = WMRA_D
    track: float = WMRA_TRACK
    mount: tuple[float, float, float] = WMRA_MOUNT
    wheel_radius: float = WMRA_WHEEL_RADIUS


def _check(d: Sequence[float], track: float, mount: Sequence[float], wheel_radius: float) -> None:
    if len(d) != 7:
        raise RobotError(f"wmra_urdf: d must hold the 7 D-H offsets d1..d7 in metres, got {len(d)} values")
    if len(mount) != 3:
        raise RobotError(f"wmra_urdf: mount must be (L2, L3, L4) in metres, got {len(mount)} values")
    values = [*d, track, *mount, wheel_radius]
    if not all(math.isfinite(float(v)) for v in values):
        raise RobotError("wmra_urdf: every dimension must be a finite number (metres)")
    if track <= 0 or wheel_radius <= 0:
        raise RobotError(f"wmra_urdf: track ({track}) and wheel_radius ({wheel_radius}) must be positive metres")
    if max(abs(float(v)) for v in values) > 10:
        raise RobotError("wmra_urdf: a dimension exceeds 10 m; pass metres, not millimetres")


#: Wheel joint orientation: local z = +y, so a positive rate rolls forward.
_WHEEL_RPY = (-math.pi / 2, 0.0, 0.0)


def _chassis(r: float) -> list[str]:
    """Return the floor link `base_footprint` and the wheelchair frame `base_link` (W) at axle height r."""
    chassis = box_inertial(WMRA_CHASSIS_MASS, (0.9, 0.6, 0.5), com=(0.25, 0.0, 0.15))
    shapes = (
        Shape("box", (0.9, 0.6, 0.08), (0.25, 0.0, 0.05), material="dark"),
        Shape("box", (0.45, 0.5, 0.08), (0.15, 0.0, 0.35), material="blue"),
        Shape("box", (0.08, 0.5, 0.55), (-0.1, 0.0, 0.6), material="blue"),
    )
    return [
        link("base_footprint"),
        link("base_link", chassis, shapes),
        joint("base_joint", "fixed", "base_footprint", "base_link", xyz=(0, 0, r)),
    ]


def _drive_wheels(track: float, r: float) -> list[str]:
    """Return the two driven wheels (radius r) on the axle through W, `track` apart (paper eq. 7-10)."""
    parts: list[str] = []
    for side, sy in (("left", 1.0), ("right", -1.0)):
        parts.append(
            link(
                f"wheel_{side}",
                cylinder_inertial(WMRA_WHEEL_MASS, r, 0.06),
                (Shape("cylinder", (r, 0.06), material="dark"),),
            )
        )
        parts.append(
            joint(
                f"wheel_{side}_joint",
                "continuous",
                "base_link",
                f"wheel_{side}",
                xyz=(0.0, sy * track / 2, 0.0),
                rpy=_WHEEL_RPY,
                limit=(0, 0, WMRA_WHEEL_EFFORT, WMRA_WHEEL_VELOCITY),
                damping=0.0,
            )
        )
    return parts


def _casters(r: float) -> list[str]:
    """Return the two front casters (swivel fork + wheel), their wheels on the floor under a base at axle height r."""
    rc = WMRA_CASTER_RADIUS
    parts: list[str] = []
    for side, sy in (("left", 1.0), ("right", -1.0)):
        parts.append(
            link(
                f"caster_{side}_fork",
                box_inertial(0.3, (0.05, 0.05, 0.1)),
                (Shape("box", (0.05, 0.05, 0.1), (0, 0, 0.02), material="grey"),),
            )
        )
        parts.append(
            joint(
                f"caster_{side}_swivel",
                "continuous",
                "base_link",
                f"caster_{side}_fork",
                xyz=(WMRA_CASTER_X, sy * WMRA_CASTER_HALF_TRACK, rc - r + 0.06),
                limit=(0, 0, 0.0, 20.0),
            )
        )
        parts.append(
            link(
                f"caster_{side}_wheel",
                cylinder_inertial(0.5, rc, 0.04),
                (Shape("cylinder", (rc, 0.04), material="dark"),),
            )
        )
        parts.append(
            joint(
                f"caster_{side}_wheel_joint",
                "continuous",
                f"caster_{side}_fork",
                f"caster_{side}_wheel",
                xyz=(-0.04, 0.0, -0.06),
                rpy=_WHEEL_RPY,
                limit=(0, 0, 0.0, 30.0),
            )
        )
    return parts


def _arm_link(i: int, parent: str, di: float) -> list[str]:
    """Return D-H link i+1 (offset di, twist WMRA_ALPHA[i]) and its revolute joint to `parent` (paper eq. 1)."""
    alpha = WMRA_ALPHA[i]
    # Modified D-H (paper eq. 1): Rotx(alpha) Tx(a=0) Rotz(q) Tz(d) = [Rotx(alpha) Tz(d)] Rotz(q).
    xyz = (0.0, -math.sin(alpha) * di, math.cos(alpha) * di)
    shapes = [Shape("sphere", (0.045,), (0, 0, 0), material="silver")]
    if abs(di) > 1e-6:
        shapes.append(Shape("cylinder", (0.035, abs(di)), (0, 0, -di / 2), material="silver"))
    mass = WMRA_LINK_MASS[i]
    inertial = combine(
        [
            cylinder_inertial(mass * 0.8, 0.035, max(abs(di), 0.05), com=(0, 0, -di / 2)),
            cylinder_inertial(mass * 0.2, 0.045, 0.09),
        ]
    )
    limit = (
        math.radians(WMRA_Q_MIN_DEG[i]),
        math.radians(WMRA_Q_MAX_DEG[i]),
        WMRA_JOINT_EFFORT[i],
        WMRA_JOINT_VELOCITY,
    )
    return [
        link(f"arm_link{i + 1}", inertial, tuple(shapes)),
        joint(f"arm_joint{i + 1}", "revolute", parent, f"arm_link{i + 1}", xyz=xyz, rpy=(alpha, 0.0, 0.0), limit=limit),
    ]


def _arm(d: Sequence[float], mount: Sequence[float]) -> list[str]:
    """Return the arm mount (frame A at `mount` in W), the 7 D-H links and the end effector `ee` (= frame 7)."""
    parts = [
        link("arm_mount", None, (Shape("box", (0.12, 0.12, 0.04), (0, 0, -0.02), material="grey"),)),
        joint("arm_mount_joint", "fixed", "base_link", "arm_mount", xyz=tuple(mount)),
    ]
    parent = "arm_mount"
    for i in range(7):
        parts.extend(_arm_link(i, parent, d[i]))
        parent = f"arm_link{i + 1}"
    parts.append(link("ee", None, (Shape("box", (0.03, 0.08, 0.02), (0, 0, 0.01), material="orange"),)))
    parts.append(joint("ee_joint", "fixed", "arm_link7", "ee"))
    return parts


def wmra_urdf(
    d: Sequence[float] = WMRA_D,
    track: float = WMRA_TRACK,
    mount: Sequence[float] = WMRA_MOUNT,
    wheel_radius: float = WMRA_WHEEL_RADIUS,
) -> str:
    """Return the URDF text of a WMRA build (paper eq. 1-2, 7-10).

    Args:
        d: D-H offsets d1..d7 of the arm, metres.
        track: distance L1 between the driven wheels, metres.
        mount: arm-base offsets (L2, L3, L4) from the drive-axle centre, metres.
        wheel_radius: driven-wheel radius L5, metres (the axle centre is L5 above the floor).

    The root link `base_footprint` lies on the floor under the axle centre;
    `robots.load` attaches it to the world with a planar joint (x, y, yaw).
    Frames: `base_link` (wheelchair frame W at the axle centre), `arm_mount`
    (frame A), `arm_link1..7` (D-H frames 1..7), `ee` (= D-H frame 7).
    """
    _check(d, track, mount, wheel_radius)
    r = float(wheel_radius)
    parts = _chassis(r) + _drive_wheels(float(track), r) + _casters(r)
    parts += _arm(tuple(float(x) for x in d), tuple(float(x) for x in mount))
    return robot("wmra", "".join(parts))
