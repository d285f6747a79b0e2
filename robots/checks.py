"""A profile checked against its URDF's Pinocchio model, and what the URDF tells about the wheels.

Every problem is a `ProfileError` naming the profile key and the fix: an unknown joint or frame, a
wheel that is not a continuous joint, an arm joint that is not a 1-DoF joint (or moves too little to be one,
or has no effort or speed), arm joints that do not carry the gripper from base to tip, an F/T frame off the
arm's chain, a differential base's wheels listed right first or with axles not across the base, a locked
value outside its joint's limits, a joint of several degrees of freedom inside the URDF, a wheel radius the
URDF does not give.
"""

from __future__ import annotations

import math
import os
import sysconfig
import xml.etree.ElementTree as ET
from collections.abc import Sequence
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


#: The kinds of Pinocchio frame a profile's frame name may be, in the order a name shared by several is read:
#: a link (URDF links and joints may share a name: Unitree Z1's ``gripperStator``, SO-100's ``gripper``),
#: then a frame of its own, then a fixed or a movable joint.
FRAME_PREFERENCE = (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT, pin.FrameType.JOINT)


def frame_id(model: pin.Model, name: str) -> int:
    """Return the id of the frame ``name`` (`FRAME_PREFERENCE`: the link of that name first).

    ``model.getFrameId(name)`` raises "Several frames match the filter" when a link and a joint share the name.
    Raises KeyError when no frame has the name.
    """
    for kind in FRAME_PREFERENCE:
        if model.existFrame(name, kind):
            return int(model.getFrameId(name, kind))
    if model.existFrame(name):
        return int(next(i for i, f in enumerate(model.frames) if f.name == name))
    raise KeyError(f"no frame {name!r}")


def is_continuous(joint: pin.JointModel) -> bool:
    """Return True for an unbounded revolute (URDF ``continuous``) joint: nq 2 (cos, sin), nv 1."""
    return joint.nq == 2 and joint.nv == 1


def _arm_joint(prof: RobotProfile, model: pin.Model, key: str, name: str) -> None:
    """Raise `ProfileError` unless ``name`` is a revolute or prismatic joint of one degree of freedom with limits."""
    src = prof.source or prof.name
    j = _joint(prof, model, key, name)
    if is_continuous(j):
        raise ProfileError(
            src,
            key,
            f"{name!r} is a continuous (unbounded) joint; arm joints need position limits: in the URDF make it "
            'type="revolute" with <limit lower="-6.2832" upper="6.2832" .../> (one turn either way), '
            "keeping its effort and velocity",
        )
    if j.nv != 1:
        raise ProfileError(
            src,
            key,
            f"{name!r} is a joint of {j.nv} degrees of freedom ({j.shortname()}); arm joints must be revolute or "
            "prismatic (one each) with limits",
        )


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
        speed = float(model.velocityLimit[j.idx_v])
        if prof.base_twist_limit is None and not (math.isfinite(speed) and speed > 0.0):
            raise ProfileError(
                src,
                f"wheel_joints[{k}]",
                f"{w!r} has no speed limit in the URDF (velocity {speed:g}; the base's speed limits come from its "
                "wheels'): give its <limit velocity> in rad/s, or the profile's [push] base_twist_limit",
            )
        used.add(w)
    for i, arm in enumerate(prof.arms):
        for k, name in enumerate(arm.joints):
            _arm_joint(prof, model, f"arms[{i}].joints[{k}]", name)
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
    _check_single_dof(prof, model)
    for i in range(len(prof.arms)):
        _check_arm_chain(prof, model, i)
    if prof.base == "differential" and len(prof.wheel_joints) == 2:
        _check_differential_wheels(prof, model)


#: The least range (rad or m) of an arm joint: the grasp IK keeps 0.02 off each limit, and a shorter range is
#: a gripper's finger or a joint that cannot move the hand.
MIN_ARM_RANGE = 0.1
#: The largest angle (deg) between a differential base's wheel axle and the line across the base (its y axis).
MAX_AXLE_TILT_DEG = 20.0


def _check_single_dof(prof: RobotProfile, model: pin.Model) -> None:
    """Raise `ProfileError` for a joint of several degrees of freedom inside the URDF (planar, floating): the
    base's motion is the profile's ``base``, on the planar root that `robots.load` adds."""
    for j in range(2, model.njoints):
        if model.joints[j].nv > 1:
            raise ProfileError(
                prof.source or prof.name,
                "urdf",
                f"joint {model.names[j]!r} is a {model.joints[j].shortname()} joint ({model.joints[j].nv} DoF); "
                "make it fixed: the base's motion comes from the profile's base key",
            )


def _check_arm_chain(prof: RobotProfile, model: pin.Model, i: int) -> None:
    """Raise `ProfileError` when arm ``i``'s joints do not move its gripper frame in order from base to tip, when
    one moves too little or has no effort or speed limit, or when its F/T frame is not beyond every arm joint
    (nor with an arm joint between it and the hand)."""
    src, arm = prof.source or prof.name, prof.arms[i]
    hand_chain = list(model.supports[model.frames[frame_id(model, arm.gripper_frame)].parentJoint])
    last = -1
    for k, name in enumerate(arm.joints):
        jid, key = model.getJointId(name), f"arms[{i}].joints[{k}]"
        if jid not in hand_chain:
            raise ProfileError(
                src,
                key,
                f"{name!r} does not move the gripper frame {arm.gripper_frame!r}; list the joints on the "
                "chain from the base to the hand (or check gripper_frame)",
            )
        if hand_chain.index(jid) < last:
            raise ProfileError(src, key, f"{name!r} is listed after a joint it carries; list the joints base to tip")
        last = hand_chain.index(jid)
        j = model.joints[jid]
        lo, hi = float(model.lowerPositionLimit[j.idx_q]), float(model.upperPositionLimit[j.idx_q])
        if not hi - lo > MIN_ARM_RANGE:
            raise ProfileError(
                src,
                key,
                f"{name!r} moves only {hi - lo:.3g} (limits [{lo:g}, {hi:g}]); an arm joint needs a range "
                f"over {MIN_ARM_RANGE:g}: a gripper finger? hold it in [locked]",
            )
        effort, speed = float(model.effortLimit[j.idx_v]), float(model.velocityLimit[j.idx_v])
        if not (effort > 0.0 and speed > 0.0):
            raise ProfileError(
                src,
                key,
                f"{name!r} has effort {effort:g} and velocity {speed:g} in the URDF; give its <limit> a "
                "positive effort and velocity",
            )
    if arm.ft_frame is not None:
        ft_chain = list(model.supports[model.frames[frame_id(model, arm.ft_frame)].parentJoint])
        ids = [model.getJointId(n) for n in arm.joints]
        between = [model.names[j] for j in ids if (j in ft_chain) != (j in hand_chain)]
        outside = [model.names[j] for j in ids if j not in ft_chain]
        if between or outside:
            raise ProfileError(
                src,
                f"arms[{i}].ft_frame",
                f"{arm.ft_frame!r} is not carried by the arm's joint "
                f"{(outside or between)[0]!r}: the F/T frame must be beyond every arm joint, on the hand's link "
                "or next to it (the wrist's sensor link)",
            )


def _check_differential_wheels(prof: RobotProfile, model: pin.Model) -> None:
    """Raise `ProfileError` when a differential base's wheels are listed right first (the left wheel is at +y of
    the root) or a wheel's axle is not across the base (along its y axis, within ``MAX_AXLE_TILT_DEG``)."""
    src = prof.source or prof.name
    data = model.createData()
    q = reference_configuration(prof, model)
    pin.computeJointJacobians(model, data, q)
    root = data.oMi[1]
    ys = []
    for k, w in enumerate(prof.wheel_joints):
        jid = model.getJointId(w)
        col = pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED)[3:, model.joints[jid].idx_v]
        axis = root.rotation.T @ col
        tilt = math.degrees(math.acos(min(1.0, abs(float(axis[1])) / max(float(np.linalg.norm(axis)), 1e-12))))
        if tilt > MAX_AXLE_TILT_DEG:
            raise ProfileError(
                src,
                f"wheel_joints[{k}]",
                f"{w!r} turns about ({axis[0]:.2f}, {axis[1]:.2f}, {axis[2]:.2f}) in the "
                f"root link's frame, {tilt:.0f} deg off its y axis; a differential base's wheel axles run across "
                "the base (check the joint's <axis> and the base link's x forward, z up)",
            )
        ys.append(float((root.inverse() * data.oMi[jid]).translation[1]))
    if not ys[0] > ys[1]:
        raise ProfileError(
            src,
            "wheel_joints",
            f"{prof.wheel_joints[0]!r} is at y = {ys[0]:.3g} m and {prof.wheel_joints[1]!r} at "
            f"y = {ys[1]:.3g} m of the root link; list the left wheel (+y) first",
        )


def _check_arms_apart(prof: RobotProfile, model: pin.Model) -> None:
    """Raise `ProfileError` when one arm's joint carries another arm's gripper frame (a joint two arms share)."""
    for i, arm in enumerate(prof.arms):
        carried = set(model.supports[model.frames[frame_id(model, arm.gripper_frame)].parentJoint])
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
            raise ProfileError(
                src,
                "wheel_radius",
                "the URDF's wheel axles are not above its root link: the robot stands with its root link on the floor; "
                "put it there (a new root link with a fixed joint to the old one at the wheel radius above it)",
            )
    separation = prof.wheel_separation
    if prof.base == "differential" and separation is None:
        separation = float(np.linalg.norm(centres[0] - centres[1]))
        if not separation > 1e-6:
            raise ProfileError(src, "wheel_separation", "the URDF's two wheels coincide; give it (m)")
    positions = prof.wheel_positions or tuple((float(c[0]), float(c[1])) for c in centres)
    return WheelGeometry(float(radius), separation, positions)


def check_wheel_radius(prof: RobotProfile, model: pin.Model, collision: pin.GeometryModel) -> None:
    """Raise `ProfileError` when a wheel's collision cylinder (or sphere) and its axle's height above the root
    link disagree by more than 10 % and the profile gives no ``wheel_radius``: the root link is then not on the
    floor, and the planner (which takes the axle's height) and the MuJoCo plant (which rolls the cylinder)
    would drive the wheels at different speeds."""
    if not prof.wheel_joints:
        return
    data = model.createData()
    pin.forwardKinematics(model, data, reference_configuration(prof, model))
    root = data.oMi[1]
    for w in prof.wheel_joints:
        jid = model.getJointId(w)
        height = float((root.inverse() * data.oMi[jid]).translation[2])
        tyres = [
            (float(obj.geometry.radius), type(obj.geometry).__name__)
            for obj in collision.geometryObjects
            if obj.parentJoint == jid and type(obj.geometry).__name__ in ("Cylinder", "Sphere")
        ]
        if prof.wheel_radius is not None:
            _check_root_on_floor(prof, model, w, height, tyres[0][0] if tyres else None)
            continue
        for r, kind in tyres[:1]:
            if abs(height - float(r)) > 0.1 * float(r):
                raise ProfileError(
                    prof.source or prof.name,
                    "wheel_radius",
                    f"wheel {w!r}: its collision {kind.lower()} has radius {float(r):.4g} m but its axle is {height:.4g} m above the "
                    f"root link: put the URDF's root link on the floor (a new root link with a fixed joint to the old "
                    f'one at xyz="0 0 {float(r) - height:.4g}"), or give the wheel\'s collision {kind.lower()} its radius',
                )


def _check_root_on_floor(prof: RobotProfile, model: pin.Model, wheel: str, height: float, tyre: float | None) -> None:
    """Raise `ProfileError` when a wheel's axle is not ``wheel_radius`` (10 %) above the URDF's root link.

    The robot stands with its root link on the floor: an axle at another height means a root link above or
    below the floor, and every height of the model (the arm's shoulder, its reach to the handle) off by the
    difference. When the wheel's collision cylinder or sphere (radius ``tyre``) agrees with the axle's height,
    the root link is on the floor and ``wheel_radius`` is what is wrong."""
    r = float(prof.wheel_radius or 0.0)
    if abs(height - r) <= 0.1 * r:
        return
    if tyre is not None and abs(height - tyre) <= 0.1 * tyre:
        raise ProfileError(
            prof.source or prof.name,
            "wheel_radius",
            f"wheel {wheel!r}: wheel_radius is {r:.4g} m but the wheel's collision shape has radius {tyre:.4g} m and "
            f"its axle is {height:.4g} m above the URDF's root link, which stands on the floor: correct wheel_radius "
            f"to {tyre:.4g} (or leave it out: it is read off the URDF)",
        )
    root = next((f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == 1), "root")
    raise ProfileError(
        prof.source or prof.name,
        "wheel_radius",
        f"wheel {wheel!r}: its axle is {height:.4g} m above the URDF's root link but wheel_radius is {r:.4g} m: the "
        f"robot stands with its root link on the floor, so it would be modelled {r - height:+.3g} m off its height; "
        f'put the root link on the floor (a new root link with a fixed joint to {root!r} at xyz="0 0 '
        f'{r - height:.4g}"), or correct wheel_radius',
    )


#: A link without mass whose collision primitives enclose this much volume (m^3) or more is a body left out.
MASSLESS_BODY_VOLUME = 0.005


def link_mass(link: ET.Element) -> float:
    """Return a URDF ``<link>``'s ``<inertial><mass value>`` (0 without one or when it is not a number)."""
    mass = link.find("inertial/mass")
    try:
        return float(mass.get("value", "0")) if mass is not None else 0.0
    except ValueError:
        return 0.0


def _primitive_volume(geometry: ET.Element) -> float:
    """Return the volume (m^3) of a URDF ``<geometry>``'s box, cylinder or sphere (0 for a mesh or nothing)."""
    try:
        if (box := geometry.find("box")) is not None:
            return float(np.prod([float(v) for v in str(box.get("size", "0 0 0")).split()]))
        if (cyl := geometry.find("cylinder")) is not None:
            return math.pi * float(cyl.get("radius", 0)) ** 2 * float(cyl.get("length", 0))
        if (sph := geometry.find("sphere")) is not None:
            return 4.0 / 3.0 * math.pi * float(sph.get("radius", 0)) ** 3
    except ValueError:
        return 0.0
    return 0.0


#: ... and the massless links together hold at least this share of the robot's collision primitives' volume
MASSLESS_BODY_SHARE = 0.33


def massless_bodies(
    urdf_text: str, min_volume: float = MASSLESS_BODY_VOLUME, min_share: float = MASSLESS_BODY_SHARE
) -> list[tuple[str, float]]:
    """Return the URDF's links without a positive ``<inertial>`` mass whose collision boxes, cylinders and spheres
    enclose ``min_volume`` or more, with that volume, when together they are ``min_share`` or more of the volume of
    every link's collision primitives: a chassis whose mass was left out (the model, kinematic and MuJoCo, then
    weighs without most of the robot; a sensor frame, a mesh-only link or a pedestal whose mass another link
    carries is not counted)."""
    out, total = [], 0.0
    for link in ET.fromstring(urdf_text).iter("link"):
        volume = sum(_primitive_volume(g) for g in link.findall("collision/geometry"))
        total += volume
        if not link_mass(link) > 0.0 and volume >= min_volume:
            out.append((str(link.get("name")), volume))
    return out if sum(v for _, v in out) >= min_share * total else []


def massless_moved_bodies(urdf_text: str, joints: Sequence[str]) -> list[str]:
    """Return the ``joints`` whose child link, with the links fixed to it, has no positive ``<inertial>`` mass
    (the body the joint moves is massless in Pinocchio's model: its weight is out of every torque)."""
    root = ET.fromstring(urdf_text)
    mass = {str(link.get("name")): link_mass(link) for link in root.iter("link")}
    fixed: dict[str, list[str]] = {}
    child_of: dict[str, str] = {}
    for j in root.iter("joint"):
        parent, child = j.find("parent"), j.find("child")
        if parent is None or child is None:
            continue
        child_of[str(j.get("name"))] = str(child.get("link"))
        if j.get("type") == "fixed":
            fixed.setdefault(str(parent.get("link")), []).append(str(child.get("link")))

    def body_mass(link: str) -> float:
        return mass.get(link, 0.0) + sum(body_mass(c) for c in fixed.get(link, ()))

    return [n for n in joints if n in child_of and not body_mass(child_of[n]) > 0.0]


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
