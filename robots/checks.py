"""A profile checked against its URDF's Pinocchio model, and what the URDF tells about the wheels.

Every problem is a `ProfileError` naming the profile key and the fix: an unknown joint or frame, a
wheel that is not a continuous joint, an arm joint that is not a 1-DoF joint, a locked value outside
its joint's limits, a wheel radius the URDF does not give.
"""

from __future__ import annotations

import math
import os
import sysconfig
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from robots.errors import ProfileError
from robots.profiles import RobotProfile


def movable_joints(model: pin.Model) -> list[str]:
    """Return the names of the model's joints with a degree of freedom, root excluded."""
    return [model.names[j] for j in range(2, model.njoints)]


def _hint(names: list[str], limit: int = 12) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f", ... ({len(names)} in all)" if len(names) > limit else "")


def _joint(prof: RobotProfile, model: pin.Model, key: str, name: str) -> pin.JointModel:
    if not model.existJointName(name) or model.getJointId(name) < 2:
        raise ProfileError(
            prof.source or prof.name,
            key,
            f"joint {name!r} is not a movable joint of {prof.urdf.name}; its movable joints: {_hint(movable_joints(model))}",
        )
    return model.joints[model.getJointId(name)]


def _frame(prof: RobotProfile, model: pin.Model, key: str, name: str) -> None:
    if not model.existFrame(name):
        links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        raise ProfileError(
            prof.source or prof.name, key, f"frame {name!r} is not in {prof.urdf.name}; its links: {_hint(links)}"
        )


def is_continuous(joint: pin.JointModel) -> bool:
    """Return True for an unbounded revolute (URDF ``continuous``) joint: nq 2 (cos, sin), nv 1."""
    return joint.nq == 2 and joint.nv == 1


def check_profile(prof: RobotProfile, model: pin.Model) -> None:
    """Raise `ProfileError` when the profile names something its URDF lacks or gets a joint type wrong."""
    src = prof.source or prof.name
    used: set[str] = set()
    for k, w in enumerate(prof.wheel_joints):
        j = _joint(prof, model, f"wheel_joints[{k}]", w)
        if not is_continuous(j):
            raise ProfileError(
                src,
                f"wheel_joints[{k}]",
                f"{w!r} is not a continuous joint (it is {j.shortname()}); list the wheels' joints",
            )
        used.add(w)
    for i, arm in enumerate(prof.arms):
        for k, name in enumerate(arm.joints):
            j = _joint(prof, model, f"arms[{i}].joints[{k}]", name)
            if j.nv != 1 or is_continuous(j):
                raise ProfileError(
                    src,
                    f"arms[{i}].joints[{k}]",
                    f"{name!r} is a {j.shortname()} joint; arm joints must be revolute or prismatic with limits",
                )
            if name in used:
                raise ProfileError(src, f"arms[{i}].joints[{k}]", f"{name!r} is used twice (arms and wheels)")
            used.add(name)
        _frame(prof, model, f"arms[{i}].gripper_frame", arm.gripper_frame)
        if arm.ft_frame is not None:
            _frame(prof, model, f"arms[{i}].ft_frame", arm.ft_frame)
    _check_arms_apart(prof, model)
    for name, value in prof.locked:
        j = _joint(prof, model, f"locked.{name}", name)
        if name in used:
            raise ProfileError(src, f"locked.{name}", "is an arm or wheel joint; remove it from [locked]")
        if j.nq == 1:
            lo, hi = model.lowerPositionLimit[j.idx_q], model.upperPositionLimit[j.idx_q]
            if not (lo - 1e-12 <= value <= hi + 1e-12):
                raise ProfileError(src, f"locked.{name}", f"{value:g} is outside the joint's limits [{lo:g}, {hi:g}]")
    for role, frame in prof.frames:
        _frame(prof, model, f"frames.{role}", frame)


def _check_arms_apart(prof: RobotProfile, model: pin.Model) -> None:
    """Raise `ProfileError` when one arm's joint carries another arm's gripper frame (a joint two arms share)."""
    for i, arm in enumerate(prof.arms):
        carried = set(model.supports[model.frames[model.getFrameId(arm.gripper_frame)].parentJoint])
        for k, other in enumerate(prof.arms):
            shared = [n for n in other.joints if k != i and model.getJointId(n) in carried]
            if shared:
                raise ProfileError(
                    prof.source or prof.name,
                    f"arms[{i}].gripper_frame",
                    f"{arm.gripper_frame!r} moves with arms[{k}]'s joint {shared[0]!r}: a joint that carries two "
                    "hands is not supported; hold it in [locked] (or list only the joints of each arm's own chain)",
                )


def reference_configuration(prof: RobotProfile, model: pin.Model) -> np.ndarray:
    """Return the configuration of every joint outside the arms and wheels: the locked values, else neutral."""
    q = pin.neutral(model)
    for name, value in prof.locked:
        j = model.joints[model.getJointId(name)]
        if is_continuous(j):
            q[j.idx_q : j.idx_q + 2] = (math.cos(value), math.sin(value))
        elif j.nq == 1:
            q[j.idx_q] = value
    return q


@dataclass(frozen=True)
class WheelGeometry:
    """The driven wheels as the base model needs them: radius, and separation (differential) or positions."""

    radius: float
    separation: float | None
    positions: tuple[tuple[float, float], ...]


def wheel_geometry(prof: RobotProfile, model: pin.Model) -> WheelGeometry:
    """Return the wheel radius, separation and positions: the profile's values, else read off the URDF.

    The URDF's root link lies on the floor, so a wheel's radius is its axle height at the neutral
    configuration; the separation is the distance between the two wheel centres; positions are the
    wheel centres' (x, y) in the root frame.
    """
    data = model.createData()
    pin.forwardKinematics(model, data, reference_configuration(prof, model))
    centres = [data.oMi[model.getJointId(w)].translation.copy() for w in prof.wheel_joints]
    src = prof.source or prof.name
    radius = prof.wheel_radius
    if radius is None:
        radius = float(centres[0][2]) if centres else 0.0
        if not radius > 1e-6:
            raise ProfileError(src, "wheel_radius", "the URDF's wheel axles are not above its root link; give it (m)")
    separation = prof.wheel_separation
    if prof.base == "differential" and separation is None:
        separation = float(np.linalg.norm(centres[0] - centres[1]))
        if not separation > 1e-6:
            raise ProfileError(src, "wheel_separation", "the URDF's two wheels coincide; give it (m)")
    positions = prof.wheel_positions or tuple((float(c[0]), float(c[1])) for c in centres)
    return WheelGeometry(float(radius), separation, positions)


def package_search_dirs(prof_dirs: tuple[Path, ...], urdf: Path) -> list[str]:
    """Return where ``package://`` URIs resolve: the profile's folders, the URDF's folder and its parents,
    ``$ROS_PACKAGE_PATH`` and the cmeel prefix's ``share`` (where pip-installed robot packages go)."""
    dirs = [Path(p) for p in prof_dirs]
    dirs += list(urdf.resolve().parents)[:6]
    dirs += [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    dirs.append(Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share")
    out: list[str] = []
    for d in dirs:
        s = str(d)
        if s not in out and d.is_dir():
            out.append(s)
    return out


def resolve_package_uri(uri: str, dirs: list[str]) -> Path | None:
    """Return the file a ``package://pkg/path`` URI names under one of `dirs`, or None."""
    rest = uri[len("package://") :]
    for d in dirs:
        p = Path(d) / rest
        if p.is_file():
            return p
    return None
