"""One MuJoCo scene, composed with `mujoco.MjSpec`: the cart (and its floor), the robots from their URDFs, the grasps.

The cart comes as a spec whose root holds a body ``cart`` with a free joint (:mod:`.mujoco_cart` or a
cart file checked by :mod:`.cart_file`); it is the scene's root, so its options, defaults and floor
stay its own (a plane floor at z = 0 is added when it has none: `mujoco_cart.floor_plane`); the scene sizes
its own memory, and the names it adds (robot prefixes, grasp sites and welds, the floor) avoid the file's.
Each robot is its URDF as `wholebody.push.mujoco_urdf` rewrites it for MuJoCo (meshes resolved, those
MuJoCo cannot read replaced by boxes with their links' inertia and reported, the profile's locked joints
fixed), imported with ``fusestatic`` off (MuJoCo would otherwise fuse every fixed link into the world: the
Ridgeback + iiwa would weigh 36 kg instead of 226.9), attached under the prefix ``r<i>/`` (``r<i>_1/`` when the
cart file uses that one) with:

- the base: an omnidirectional base gets a planar joint set (slide x, slide y, hinge z) under velocity
  servos (its mecanum rollers are not simulated); a differential base gets a free joint, sphere tyres
  on its driven wheels and free wheels (casters) and frictionless balls on its other geoms on the floor
  (fixed ball casters; `floor_contacts`; nothing else of the robot collides), and velocity servos on its
  two wheel joints; with nothing on the floor but its wheels it becomes a planar base (a warning says so);
- the arm: motors (joint torques within the URDF's effort limits) for a torque-controlled arm,
  velocity servos for a velocity-controlled one (:mod:`.arm_control` decides which);
- the F/T sensor: force and torque sensors at a site placed at the profile's F/T frame, on the first
  body of the hand's chain beyond it (MuJoCo senses the force between a body and its parent; the
  bodies beyond the sensor, e.g. the gripper, are the sensor's tool load);
- the grasp: a weld equality between a site at the hand (the end-effector frame) and a site on the cart
  at the grasp pose, with a soft ``solref``/``solimp``: the compliant connection of a real grip.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import mujoco
import numpy as np

from robots.checks import link_mass
from wholebody.errors import WholeBodyError
from wholebody.push.mujoco_cart import floor_plane, geom_lowest_z
from wholebody.push.file_version import file_version
from wholebody.push.mujoco_urdf import MujocoUrdf, mujoco_urdf


class SceneCompositionError(WholeBodyError):
    """A robot or cart that cannot be composed into a MuJoCo scene (missing frame, joint or body)."""


class MujocoSceneWarning(UserWarning):
    """A robot entered the scene changed: meshes MuJoCo cannot read replaced, a base without casters made planar."""


#: Kinds of arm actuation: joint torque motors, or joint velocity servos.
ARM_TORQUE, ARM_VELOCITY = "torque", "velocity"


@dataclass(frozen=True)
class GraspCompliance:
    """The weld between hand and handle: MuJoCo ``solref`` (time constant s, damping ratio) and ``solimp``.

    A time constant of 5 ms (>= 2 physics steps at 500 Hz) with critical damping: under the push loads
    (tens of N) the hand moves by millimetres relative to the handle (the plant reports the largest slip).
    """

    solref: tuple[float, float] = (0.005, 1.0)
    solimp: tuple[float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)[:3]
    #: scale of the weld's rotational residual relative to its translational one (MuJoCo ``torquescale``)
    torquescale: float = 1.0


@dataclass(frozen=True)
class ServoGains:
    """Velocity-servo gains (N s/m, N m s/rad) and force limits of the bases and the velocity-controlled arm."""

    #: planar base: per unit of the robot's mass (1/s), i.e. the servo's bandwidth at rigid load
    base_bandwidth: float = 40.0
    base_force_limit: float = 4000.0
    base_torque_limit: float = 2000.0
    #: planar base: integral action (1/s) on the velocity error (a wheel drive's PI loop): the base does not fall
    #: behind the commanded path while it accelerates (a P servo lags by acceleration / bandwidth, adding up over a
    #: ramp: 2 cm over Traj. 2's start, enough to stretch the iiwa's elbow); bounded to `base_integral_limit` (m, rad).
    #: Off by default: measured, 10/s keeps Traj. 2 closer through its first turn but does not stop its divergence,
    #: and Traj. 1 without estimation then diverges at its final stop (docs/mujoco.md)
    base_integral: float = 0.0
    base_integral_limit: float = 0.05
    #: differential drive wheels: kv (N m s/rad); the servo's force is not limited: the wheel joint's effort limit
    #: (the URDF import's actuator-force clamp on the joint) bounds what it applies
    wheel_kv: float = 60.0
    #: velocity-controlled arm joints: kv (N m s/rad); the servo's force is not limited: the joint's effort limit
    #: (its actuator-force clamp from the URDF import) bounds what it applies
    arm_kv: float = 80.0


@dataclass(frozen=True)
class RobotSetup:
    """What the scene needs of one robot: its URDF, profile, initial state and arm actuation."""

    name: str
    urdf: str
    #: "differential" (a free-joint base on its wheels) or "planar" (any holonomic base: planar joints)
    base: str
    arm_joints: tuple[str, ...]
    #: the driven wheels' joints (differential: left, right)
    wheel_joints: tuple[str, ...]
    #: (3 + n_arm,) base pose (x, y, yaw) and arm joints, holding the handle
    x: np.ndarray
    #: "torque" or "velocity"
    arm_mode: str
    #: name of the link of the end effector (the hand) and of the F/T sensor
    ee_link: str
    ft_link: str
    #: (4, 4) the hand's pose in the cart frame {b} at the start (where the grasp site goes)
    T_b_hand: np.ndarray = field(default_factory=lambda: np.eye(4))
    #: extra folders where the URDF's ``package://`` meshes resolve (the profile's ``package_dirs``)
    package_dirs: tuple[str, ...] = ()
    #: (joint, value) of the profile's locked joints; every movable joint outside the arm, the wheels and the
    #: casters is held (made fixed) at its value here, or at 0
    locked: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class RobotIndex:
    """Addresses of one robot in the compiled scene."""

    prefix: str
    base: str  # "planar" or "free"
    base_qpos: np.ndarray
    base_dof: np.ndarray
    arm_qpos: np.ndarray
    arm_dof: np.ndarray
    arm_actuators: np.ndarray
    #: velocity-servoed arms: motors holding the static load (the drives' integral action); empty otherwise
    arm_hold_actuators: np.ndarray
    base_actuators: np.ndarray  # planar: (x, y, yaw) velocity servos
    wheel_actuators: np.ndarray  # differential: (left, right) velocity servos
    wheel_qpos: np.ndarray
    wheel_dof: np.ndarray
    wheel_bodies: np.ndarray
    wheel_radius: float
    root_body: int
    ee_body: int
    hand_site: int
    handle_site: int
    ft_site: int
    weld: int
    force_adr: int
    torque_adr: int
    #: mass (kg) and CoM (3,) in the F/T site frame of the bodies beyond the sensor (the tool load)
    tool_mass: float
    tool_com: np.ndarray
    effort_limit: np.ndarray
    #: the meshes MuJoCo could not read and what replaced them (`mujoco_urdf.MujocoUrdf.replaced_meshes`)
    replaced_meshes: tuple[str, ...] = ()
    #: how the base is simulated ("wheels": driven wheels and supports on the floor; "planar": planar servos)
    base_model: str = "planar"


@dataclass
class Scene:
    """The compiled scene: model, data, the cart body id and one `RobotIndex` per robot."""

    model: mujoco.MjModel
    data: mujoco.MjData
    cart_body: int
    cart_qpos: int
    cart_dof: int
    robots: list[RobotIndex]


# --------------------------------------------------------------------------- geometry helpers


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Return the unit quaternion (w, x, y, z) of a rotation matrix."""
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(9))
    return q


def yaw_quat(yaw: float) -> np.ndarray:
    """Return the quaternion of a rotation by `yaw` about z."""
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def _urdf_spec(urdf_text: str) -> mujoco.MjSpec:
    """Return a robot's URDF text (`robot_urdf`) as a spec with fixed links kept as bodies, visuals discarded."""
    try:
        spec = mujoco.MjSpec.from_string(urdf_text)
    except ValueError as exc:
        raise SceneCompositionError(f"MuJoCo cannot read the URDF: {str(exc).splitlines()[0]}") from None
    spec.compiler.fusestatic = False
    spec.compiler.discardvisual = True
    return spec


def _compile_urdf(urdf_text: str, robot: str) -> mujoco.MjModel:
    try:
        return _urdf_spec(urdf_text).compile()
    except ValueError as exc:  # MuJoCo's compiler error
        first = str(exc).splitlines()[0]
        massless = massless_moving_links(urdf_text) if "mjMINVAL" in first else []
        hint = (
            f" (links on a moving joint without mass: {', '.join(massless)}; give each an <inertial>)"
            if massless
            else ""
        )
        raise SceneCompositionError(f"robot {robot!r}: its URDF does not compile in MuJoCo: {first}{hint}") from None


def massless_moving_links(urdf_text: str) -> list[str]:
    """Return the URDF's links that a non-fixed joint moves and that have no ``<inertial>`` or a mass <= 0
    (MuJoCo refuses a moving body without mass; Pinocchio takes it as massless)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(urdf_text)
    children = [(j.get("type"), j.find("child")) for j in root.iter("joint")]
    moving = {c.get("link") for kind, c in children if kind != "fixed" and c is not None}
    return [
        str(link.get("name")) for link in root.iter("link") if link.get("name") in moving and not link_mass(link) > 0.0
    ]


def _ancestors(model: mujoco.MjModel, body: int) -> list[int]:
    """Return [body, its parent, ..., world] ids."""
    chain = [body]
    while chain[-1] != 0:
        chain.append(int(model.body_parentid[chain[-1]]))
    return chain


def _body_id(model: mujoco.MjModel, name: str, robot: str) -> int:
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid < 0:
        raise SceneCompositionError(f"robot {robot!r}: no link {name!r} in its URDF")
    return bid


def sensor_placement(
    urdf_text: str, ee_link: str, ft_link: str, robot: str
) -> tuple[str, np.ndarray, float, np.ndarray]:
    """Return (sensor body, F/T frame pose (4, 4) in it, tool mass, tool CoM in the F/T frame).

    The sensor body is the first body on the hand's chain beyond the F/T link, or the hand's own body when
    the hand is at the F/T link or before it (TIAGo's ``arm_tool_link``, 8 mm before ``wrist_ft_link``):
    MuJoCo's force sensor measures what that body's parent transmits to its subtree, i.e. the hand's
    load plus the tool beyond the sensor. `urdf_text` is the robot's URDF as `robot_urdf` makes it.
    """
    model = _compile_urdf(urdf_text, robot)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    ee, ft = _body_id(model, ee_link, robot), _body_id(model, ft_link, robot)
    ft_chain = set(_ancestors(model, ft))
    beyond = [b for b in _ancestors(model, ee) if b not in ft_chain]
    if beyond and int(model.body_parentid[beyond[-1]]) not in ft_chain:
        raise SceneCompositionError(f"robot {robot!r}: the hand {ee_link!r} is not beyond the F/T frame {ft_link!r}")
    sensor = beyond[-1] if beyond else ee
    subtree = [b for b in range(model.nbody) if sensor in _ancestors(model, b)]
    if any(model.body_jntnum[b] for b in subtree):
        raise SceneCompositionError(f"robot {robot!r}: a joint between the F/T frame {ft_link!r} and the hand")
    T_ws, T_wf = np.eye(4), np.eye(4)
    T_ws[:3, :3], T_ws[:3, 3] = data.xmat[sensor].reshape(3, 3), data.xpos[sensor]
    T_wf[:3, :3], T_wf[:3, 3] = data.xmat[ft].reshape(3, 3), data.xpos[ft]
    T_sf = np.linalg.inv(T_ws) @ T_wf
    masses = model.body_mass[subtree]
    mass = float(masses.sum())
    com_w = (masses[:, None] * data.xipos[subtree]).sum(axis=0) / mass if mass > 0 else T_wf[:3, 3]
    com_f = T_wf[:3, :3].T @ (com_w - T_wf[:3, 3])
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, sensor)
    return name, T_sf, mass, com_f


# --------------------------------------------------------------------------- composition


#: a geom whose lowest point is within this distance (m) of the floor (the driven wheels' lowest point) touches it
FLOOR_TOLERANCE = 0.005
#: radius (m) of the ball that stands for a support that is neither a wheel nor a sphere
SUPPORT_BALL_RADIUS = 0.01
#: suffix of the geoms that touch the floor (tyres and supports); every other robot geom collides with nothing
CONTACT_SUFFIX = "_tyre"


@dataclass(frozen=True)
class Support:
    """A robot geom on the floor: a driven wheel, a free wheel (caster) or a ball (a fixed caster, a skid)."""

    body: str
    #: "driven", "wheel" (both: a sphere tyre with friction) or "ball" (a frictionless sphere)
    kind: str
    radius: float
    #: (3,) the sphere's centre in the body frame
    pos: tuple[float, float, float]


@dataclass(frozen=True)
class RobotUrdf:
    """A robot as MuJoCo takes it: its URDF text (`mujoco_urdf`), base model, floor contacts and notes."""

    urdf: MujocoUrdf
    #: "planar" (planar joints under servos) or "differential" (a free joint on driven wheels and supports)
    base: str
    supports: tuple[Support, ...] = ()
    #: height (m) of the floor in the URDF root's frame (the driven wheels' lowest point)
    floor_z: float = 0.0
    notes: tuple[str, ...] = ()


def _subtree_bodies(model: mujoco.MjModel, joints: Sequence[int]) -> set[int]:
    """Return the bodies at or below the bodies of `joints`."""
    tops = {int(model.jnt_bodyid[j]) for j in joints}
    return {b for b in range(model.nbody) if tops & set(_ancestors(model, b))}


def _driven_wheels(model: mujoco.MjModel, data: mujoco.MjData, wheel_joints: Sequence[int]) -> list[Support]:
    """Return the driven wheels: a tyre of the wheel's cylinder radius, else of the axle's height above the root."""
    out = []
    for j in wheel_joints:
        b = int(model.jnt_bodyid[j])
        cyl = [
            g
            for g in range(model.ngeom)
            if model.geom_bodyid[g] == b and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER
        ]
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b)
        if cyl:
            out.append(Support(name, "driven", float(model.geom_size[cyl[0]][0]), tuple(model.geom_pos[cyl[0]])))
        else:  # the profile's default wheel radius: the axle's height above the root link
            radius = float(data.xanchor[j][2] - data.xpos[1][2])
            out.append(
                Support(name, "driven", radius, tuple(data.xmat[b].reshape(3, 3).T @ (data.xanchor[j] - data.xpos[b])))
            )
    return out


def _support(model: mujoco.MjModel, data: mujoco.MjData, g: int, bottom: float) -> Support:
    """Return the support geom `g` (on the floor) stands for: a wheel, its own sphere or a small ball."""
    b = int(model.geom_bodyid[g])
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b)
    rolls = any(model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE for j in range(model.njnt) if model.jnt_bodyid[j] == b)
    gtype = int(model.geom_type[g])
    if rolls and gtype == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return Support(name, "wheel", float(model.geom_size[g][0]), tuple(model.geom_pos[g]))
    if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
        return Support(name, "ball", float(model.geom_size[g][0]), tuple(model.geom_pos[g]))
    centre_w = np.array([data.geom_xpos[g][0], data.geom_xpos[g][1], bottom + SUPPORT_BALL_RADIUS])
    pos = data.xmat[b].reshape(3, 3).T @ (centre_w - data.xpos[b])
    return Support(name, "ball", SUPPORT_BALL_RADIUS, tuple(pos))


def floor_contacts(
    model: mujoco.MjModel, arm_joints: Sequence[str], wheel_joints: Sequence[str]
) -> tuple[float, list[Support], list[int]]:
    """Return (floor height, supports, their geoms): the driven wheels, then every geom on the floor.

    At the model's reference configuration (qpos0: the locked joints are fixed at their values), the floor
    is the driven wheels' lowest point; a geom outside the arm whose lowest point is within
    `FLOOR_TOLERANCE` of it is a support (the geoms of the driven wheels excepted).
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    ids = {n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in (*arm_joints, *wheel_joints)}
    missing = [n for n, j in ids.items() if j < 0]
    if missing:
        raise SceneCompositionError(f"no movable joint {missing[0]!r} in the robot's URDF (an arm or wheel joint)")
    wheels = [ids[n] for n in wheel_joints]
    driven = _driven_wheels(model, data, wheels)
    floor = float(
        np.mean(
            [
                data.xpos[model.jnt_bodyid[j]][2]
                + np.asarray(w.pos) @ data.xmat[model.jnt_bodyid[j]].reshape(3, 3)[2]
                - w.radius
                for j, w in zip(wheels, driven)
            ]
        )
    )
    skip = _subtree_bodies(model, [ids[n] for n in arm_joints]) | {int(model.jnt_bodyid[j]) for j in wheels}
    supports, geoms = list(driven), []
    for g in range(model.ngeom):
        if int(model.geom_bodyid[g]) in skip:
            continue
        bottom = geom_lowest_z(model, data, g)
        if abs(bottom - floor) <= FLOOR_TOLERANCE:
            supports.append(_support(model, data, g, bottom))
            geoms.append(g)
    return floor, supports, geoms


@lru_cache(maxsize=16)
def _robot_urdf(
    urdf: str,
    package_dirs: tuple[str, ...],
    locked: tuple[tuple[str, float], ...],
    arm: tuple[str, ...],
    wheels: tuple[str, ...],
    base: str,
    robot: str,
    version: tuple[int, int] | None,
) -> RobotUrdf:
    movable = arm + wheels
    if base != "differential":
        return RobotUrdf(mujoco_urdf(urdf, package_dirs, dict(locked), movable), "planar")
    loose = _compile_urdf(mujoco_urdf(urdf, package_dirs).text, robot)  # every joint movable: which carry supports?
    qpos = loose.qpos0.copy()
    for name, value in locked:
        j = mujoco.mj_name2id(loose, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j >= 0:
            qpos[loose.jnt_qposadr[j]] = value
    loose.qpos0[:] = qpos
    _, _, geoms = floor_contacts(loose, arm, wheels)
    bodies = {int(loose.geom_bodyid[g]) for g in geoms}
    carriers = {
        mujoco.mj_id2name(loose, mujoco.mjtObj.mjOBJ_JOINT, j)
        for j in range(loose.njnt)
        if bodies & _subtree_bodies(loose, [j])
    }
    text = mujoco_urdf(urdf, package_dirs, dict(locked), movable + tuple(sorted(carriers)))
    floor, supports, _ = floor_contacts(_compile_urdf(text.text, robot), arm, wheels)
    if not any(s.kind != "driven" for s in supports):
        note = (
            f"robot {robot!r}: no caster or support of its differential base is on the floor (within "
            f"{FLOOR_TOLERANCE} m of its wheels' lowest point): simulated as a planar base under velocity servos"
        )
        return RobotUrdf(text, "planar", (), 0.0, (note,))
    return RobotUrdf(text, "differential", tuple(supports), floor)


def robot_urdf(setup: RobotSetup) -> RobotUrdf:
    """Return the robot as MuJoCo takes it (cached per URDF and its version, folders, locked values, joints and base).

    Every movable joint but the arm's, the wheels' and those that carry a floor contact (a caster's swivel
    and wheel) is fixed at its locked value. A differential base rolls on its driven wheels and on every
    other geom on the floor (`floor_contacts`); without any it becomes a planar base (a note says so).
    """
    return _robot_urdf(
        setup.urdf,
        tuple(setup.package_dirs),
        tuple(setup.locked),
        tuple(setup.arm_joints),
        tuple(setup.wheel_joints),
        setup.base,
        setup.name,
        file_version(setup.urdf),
    )


def _add_supports(spec: mujoco.MjSpec, supports: Sequence[Support], floor: tuple[int, int, int]) -> None:
    """Add a sphere per support: tyres with friction on wheels, frictionless balls elsewhere."""
    for k, s in enumerate(supports):
        wheel = s.kind in ("driven", "wheel")
        spec.body(s.body).add_geom(
            name=f"{s.body}{'' if wheel else f'_ball{k}'}{CONTACT_SUFFIX}",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[s.radius, 0, 0],
            pos=list(s.pos),
            mass=0.0,
            contype=floor[1],
            conaffinity=floor[0],
            condim=3 if wheel else 1,
            friction=[1.0, 0.005, 0.0001],
            priority=0 if wheel else floor[2] + 1,  # a contact takes the larger condim unless a geom has priority
        )


def _disable_collisions(spec: mujoco.MjSpec) -> None:
    for g in spec.geoms:
        if not g.name.endswith(CONTACT_SUFFIX):
            g.contype = 0
            g.conaffinity = 0


def _taken_names(model: mujoco.MjModel) -> set[str]:
    """Return every name of a compiled model (bodies, geoms, sites, joints, equalities, assets, ...): the names the
    scene's own must not repeat."""
    return {name for name in bytes(model.names).decode("utf-8", "replace").split("\0") if name}


def _free_name(base: str, taken: set[str], prefix: bool = False) -> str:
    """Return the first of `base`, `base_1`, `base_2`, ... that is not in `taken` (with `prefix`: that no name in
    `taken` starts with, followed by ``/``: a robot's prefix); add it to `taken`."""
    k = 0
    while True:
        name = base if k == 0 else f"{base}_{k}"
        clash = any(t.startswith(name + "/") for t in taken) if prefix else name in taken
        if not clash:
            taken.add(name + "/" if prefix else name)
            return name
        k += 1


def _free_bit(cart: mujoco.MjModel, skip: int | None) -> int:
    """Return a collision bit (``1 << k``) no geom of the cart spec compiled alone uses but geom `skip` (its floor):
    the robots' supports and the floor share it, so they touch each other and nothing of the cart."""
    used = 0
    for g in range(cart.ngeom):
        if g != skip:
            used |= int(cart.geom_contype[g]) | int(cart.geom_conaffinity[g])
    free = [k for k in range(30, 0, -1) if not used >> k & 1]
    return 1 << free[0] if free else 0


def _spec_floor(scene: mujoco.MjSpec, cart: mujoco.MjModel, g: int) -> mujoco.MjsGeom | None:
    """Return the spec's geom of the cart model's floor plane `g` (by name; an unnamed one by its place among the
    world's geoms, which come first in the model), or None when it cannot be told."""
    name = mujoco.mj_id2name(cart, mujoco.mjtObj.mjOBJ_GEOM, g)
    if name:
        return scene.geom(name)
    world = list(scene.worldbody.geoms)
    return world[g] if g < len(world) and world[g].type == mujoco.mjtGeom.mjGEOM_PLANE else None


def _floor_bits(scene: mujoco.MjSpec, cart: mujoco.MjModel, taken: set[str]) -> tuple[int, int, int]:
    """Return (contype, conaffinity, priority) the robots' supports collide with the floor by (`_add_supports`).

    The floor is `mujoco_cart.floor_plane` of `cart` (the cart spec compiled alone); without one a plane at z = 0
    is added under a name not in `taken`. The supports' contype is a bit no cart geom uses (`_free_bit`), added to
    the floor's conaffinity, and their conaffinity is 0: a robot's tyres and casters roll on the floor and pass
    through the cart and each other, whatever bits the file gives (with a file whose every geom collides, two
    WMRAs side by side pushed each other's casters apart and lost the cart)."""
    g = floor_plane(cart)
    bit = _free_bit(cart, g)
    if g is None:
        scene.worldbody.add_geom(
            name=_free_name("floor", taken),
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            size=[0, 0, 1],
            contype=1,
            conaffinity=1 | bit,
        )
        return (0, bit, 0) if bit else (1, 1, 0)
    floor = _spec_floor(scene, cart, g)
    if floor is None or not bit:
        return int(cart.geom_contype[g]), int(cart.geom_conaffinity[g]), int(cart.geom_priority[g])
    floor.conaffinity = int(floor.conaffinity) | bit
    return 0, bit, int(cart.geom_priority[g])


def _warn(setup: RobotSetup, prepared: RobotUrdf) -> None:
    """Warn of the meshes replaced (`RobotIndex.replaced_meshes` has the details) and of a base made planar."""
    replaced = prepared.urdf.replaced_meshes
    if replaced:
        reasons = sorted({m.reason for m in replaced})
        named = dict.fromkeys(f"{m.link} ({m.mesh.rsplit('/', 1)[-1]})" for m in replaced)  # a link's visual and
        files = ", ".join(named)  # collision shapes often name the same file: once each
        warnings.warn(
            f"robot {setup.name!r}: {len(named)} meshes MuJoCo cannot read ({'; '.join(reasons)}) replaced by "
            f"boxes with their links' inertia (the URDF's mass and inertia are kept; robot geoms do not collide): {files}",
            MujocoSceneWarning,
            stacklevel=3,
        )
    for note in prepared.notes:
        warnings.warn(note, MujocoSceneWarning, stacklevel=3)


def _prepare_robot(
    scene: mujoco.MjSpec, setup: RobotSetup, i: int, floor: tuple[int, int, int], taken: set[str]
) -> dict:
    """Attach robot `i` to the scene (joints, tyres, sensor site, hand site) under a prefix (``r<i>/``) and pick
    its grasp's name (``grasp<i>``), each clear of the names in `taken`; return the names to index later."""
    prefix = _free_name(f"r{i}", taken, prefix=True) + "/"
    grasp = _free_name(f"grasp{i}", taken)
    prepared = robot_urdf(setup)
    _warn(setup, prepared)
    spec = _urdf_spec(prepared.urdf.text)
    root = spec.worldbody.first_body()
    if root is None:
        raise SceneCompositionError(f"robot {setup.name!r}: its URDF has no link")
    if setup.base not in ("planar", "differential"):
        raise SceneCompositionError(f"robot {setup.name!r}: base {setup.base!r} is neither 'planar' nor 'differential'")
    if prepared.base == "planar":
        root.add_joint(name="base_x", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0])
        root.add_joint(name="base_y", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 1, 0])
        root.add_joint(name="base_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    else:
        _add_supports(spec, prepared.supports, floor)
        root.pos = [0.0, 0.0, -prepared.floor_z]  # the wheels on the floor
        root.add_freejoint(name="base_free")
    _disable_collisions(spec)
    spec.compiler.discardvisual = False  # keep the (now collision-free) shapes for viewers
    sensor_body, T_sf, tool_mass, tool_com = sensor_placement(
        prepared.urdf.text, setup.ee_link, setup.ft_link, setup.name
    )
    spec.body(sensor_body).add_site(name="ft", pos=T_sf[:3, 3], quat=quat_from_matrix(T_sf[:3, :3]), size=[0.01, 0, 0])
    spec.body(setup.ee_link).add_site(name="hand", size=[0.01, 0, 0])
    frame = scene.worldbody.add_frame()
    scene.attach(spec, prefix=prefix, frame=frame)
    return {
        "prefix": prefix,
        "grasp": grasp,
        "base": prepared.base,
        "tool": (tool_mass, tool_com),
        "meshes": tuple(str(m) for m in prepared.urdf.replaced_meshes),
        "model": "wheels" if prepared.base == "differential" else "planar",
    }


def _add_robot_elements(
    scene: mujoco.MjSpec,
    setup: RobotSetup,
    names: dict,
    compliance: GraspCompliance,
    gains: ServoGains,
    robot_inertia: tuple[float, float],
) -> None:
    """Add the grasp weld, the servos/motors and the F/T sensors of a robot (after attaching it; `names` from
    `_prepare_robot`)."""
    p, grasp = names["prefix"], names["grasp"]
    T = setup.T_b_hand
    scene.body("cart").add_site(name=grasp, pos=T[:3, 3], quat=quat_from_matrix(T[:3, :3]), size=[0.012, 0, 0])
    scene.add_equality(
        name=grasp,
        type=mujoco.mjtEq.mjEQ_WELD,
        objtype=mujoco.mjtObj.mjOBJ_SITE,
        name1=f"{p}hand",
        name2=grasp,
        solref=list(compliance.solref),
        solimp=list(compliance.solimp) + [0.5, 2.0],
        data=[0.0] * 10 + [compliance.torquescale, 0.0],
    )
    if names["base"] == "planar":
        mass, yaw_inertia = robot_inertia
        kv = gains.base_bandwidth
        _velocity_servo(scene, f"{p}base_x", kv * mass, gains.base_force_limit)
        _velocity_servo(scene, f"{p}base_y", kv * mass, gains.base_force_limit)
        _velocity_servo(scene, f"{p}base_yaw", kv * yaw_inertia, gains.base_torque_limit)
    else:
        for jn in setup.wheel_joints:
            _velocity_servo(scene, f"{p}{jn}", gains.wheel_kv, None)
    for jn in setup.arm_joints:
        if setup.arm_mode == ARM_TORQUE:
            act = scene.add_actuator(name=f"{p}{jn}_motor", target=f"{p}{jn}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_motor()
        else:  # a velocity servo; its drive's integral action holds the static load (a motor fed the bias forces)
            _velocity_servo(scene, f"{p}{jn}", gains.arm_kv, None)
            act = scene.add_actuator(name=f"{p}{jn}_hold", target=f"{p}{jn}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_motor()
    scene.add_sensor(
        name=f"{p}ft_force", type=mujoco.mjtSensor.mjSENS_FORCE, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"{p}ft"
    )
    scene.add_sensor(
        name=f"{p}ft_torque", type=mujoco.mjtSensor.mjSENS_TORQUE, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"{p}ft"
    )


def _velocity_servo(scene: mujoco.MjSpec, joint: str, kv: float, limit: float | None) -> None:
    act = scene.add_actuator(name=f"{joint}_servo", target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.set_to_velocity(kv=kv)
    if limit is not None:
        act.forcelimited = True
        act.forcerange = [-limit, limit]


def robot_inertia(urdf_text: str, robot: str = "robot") -> tuple[float, float]:
    """Return (mass, yaw inertia about the root link's origin) of a robot (URDF text, `robot_urdf`) at qpos0."""
    from wholebody.push.mujoco_cart import composite_inertia

    model = _compile_urdf(urdf_text, robot)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    mass, com, izz = composite_inertia(model, data)
    return mass, izz + mass * float(com[0] ** 2 + com[1] ** 2)


def compose(
    cart_spec: mujoco.MjSpec,
    cart_pose: Sequence[float] | np.ndarray,
    cart_z: float,
    setups: Sequence[RobotSetup],
    physics_dt: float,
    compliance: GraspCompliance = GraspCompliance(),
    gains: ServoGains = ServoGains(),
) -> Scene:
    """Return the compiled scene: the cart at `cart_pose` ({b} at height `cart_z`), the robots in their states.

    `cart_spec` is consumed (robots are attached to it). The state is set but not settled: the grasps
    hold from the first step.
    """
    scene = cart_spec
    scene.compiler.fusestatic = False
    scene.option.timestep = physics_dt
    alone = _compile(scene)  # the cart alone: its floor, its names and the memory it asks for
    taken = _taken_names(alone)
    floor = _floor_bits(scene, alone, taken)
    names = [_prepare_robot(scene, s, i, floor, taken) for i, s in enumerate(setups)]
    for s, n in zip(setups, names):
        _add_robot_elements(scene, s, n, compliance, gains, robot_inertia(robot_urdf(s).urdf.text, s.name))
    model = _compile_sized(scene, int(alone.narena))
    data = mujoco.MjData(model)
    cart = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "cart")
    cart_jnt = int(model.body_jntadr[cart])
    out = Scene(model, data, cart, int(model.jnt_qposadr[cart_jnt]), int(model.jnt_dofadr[cart_jnt]), [])
    out.robots = [_index(model, s, n) for s, n in zip(setups, names)]
    set_state(out, cart_pose, cart_z, [s.x for s in setups])
    _orient_wheel_servos(out)
    return out


def _orient_wheel_servos(scene: Scene) -> None:
    """Give each driven wheel's servo the sign of its joint axis along the base's y (left) axis as its gear.

    The push commands forward-positive wheel rates (a positive rate rolls the base forward); a URDF may turn a
    wheel about -y (mirrored wheel frames are common), and its servo would then drive that wheel backwards.
    """
    m, d = scene.model, scene.data
    for r in scene.robots:
        if not r.wheel_actuators.size:
            continue
        base_y = d.xmat[r.root_body].reshape(3, 3)[:, 1]
        for act in r.wheel_actuators:
            axis = d.xaxis[int(m.actuator_trnid[act, 0])]
            m.actuator_gear[act, 0] = 1.0 if float(axis @ base_y) >= 0.0 else -1.0


def _compile(scene: mujoco.MjSpec) -> mujoco.MjModel:
    """Return the compiled scene, or raise SceneCompositionError with MuJoCo's message."""
    try:
        return scene.compile()
    except ValueError as exc:  # MuJoCo's compiler error
        raise SceneCompositionError(f"the MuJoCo scene does not compile: {str(exc).splitlines()[0]}") from None


def _compile_sized(scene: mujoco.MjSpec, cart_arena: int) -> mujoco.MjModel:
    """Return the compiled scene with its own memory: MuJoCo's size for the whole scene (the cart file's
    ``<size memory>`` sized the cart alone, too small for the robots), or the cart's `cart_arena` (bytes) when
    that is larger."""
    scene.memory, scene.nstack = -1, -1
    model = _compile(scene)
    if cart_arena > int(model.narena):
        scene.memory = cart_arena
        model = _compile(scene)
    return model


def _jid(model: mujoco.MjModel, name: str) -> int:
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if j < 0:
        raise SceneCompositionError(f"no joint {name!r} in the scene")
    return j


def _aid(model: mujoco.MjModel, name: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)


def _tyre_radius(model: mujoco.MjModel, wheel_bodies: np.ndarray) -> float:
    """Return the radius of the first driven wheel's tyre sphere (0 without wheels or tyre)."""
    if not len(wheel_bodies):
        return 0.0
    name = f"{mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(wheel_bodies[0]))}_tyre"
    tyre = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
    return float(model.geom_size[tyre][0]) if tyre >= 0 else 0.0


def _index(model: mujoco.MjModel, s: RobotSetup, names: dict) -> RobotIndex:
    """Return the addresses of robot `s` in the compiled scene (`names` from `_prepare_robot`)."""
    p = names["prefix"]
    arm_j = [_jid(model, p + n) for n in s.arm_joints]
    wheel_j = [_jid(model, p + n) for n in s.wheel_joints]
    if names["base"] == "planar":
        base_j = [_jid(model, p + n) for n in ("base_x", "base_y", "base_yaw")]
        base_qpos = np.array([model.jnt_qposadr[j] for j in base_j])
        base_dof = np.array([model.jnt_dofadr[j] for j in base_j])
        base_act = np.array([_aid(model, f"{p}{n}_servo") for n in ("base_x", "base_y", "base_yaw")])
        wheel_act = np.zeros(0, dtype=int)
    else:
        fj = _jid(model, p + "base_free")
        base_qpos = np.arange(model.jnt_qposadr[fj], model.jnt_qposadr[fj] + 7)
        base_dof = np.arange(model.jnt_dofadr[fj], model.jnt_dofadr[fj] + 6)
        base_act = np.zeros(0, dtype=int)
        wheel_act = np.array([_aid(model, f"{p}{n}_servo") for n in s.wheel_joints])
    suffix = "_motor" if s.arm_mode == ARM_TORQUE else "_servo"
    sensor_f = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, f"{p}ft_force")
    sensor_t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, f"{p}ft_torque")
    wheel_bodies = np.array([model.jnt_bodyid[j] for j in wheel_j], dtype=int)
    radius = _tyre_radius(model, wheel_bodies)
    limit = np.array([model.jnt_actfrcrange[j][1] if model.jnt_actfrclimited[j] else np.inf for j in arm_j])
    return RobotIndex(
        prefix=p,
        base=names["base"],
        base_qpos=base_qpos,
        base_dof=base_dof,
        arm_qpos=np.array([model.jnt_qposadr[j] for j in arm_j]),
        arm_dof=np.array([model.jnt_dofadr[j] for j in arm_j]),
        arm_actuators=np.array([_aid(model, f"{p}{n}{suffix}") for n in s.arm_joints]),
        arm_hold_actuators=np.array(
            [_aid(model, f"{p}{n}_hold") for n in s.arm_joints] if s.arm_mode == ARM_VELOCITY else [], dtype=int
        ),
        base_actuators=base_act,
        wheel_actuators=wheel_act,
        wheel_qpos=np.array([model.jnt_qposadr[j] for j in wheel_j], dtype=int),
        wheel_dof=np.array([model.jnt_dofadr[j] for j in wheel_j], dtype=int),
        wheel_bodies=wheel_bodies,
        wheel_radius=radius,
        root_body=int(model.body_rootid[_body_id(model, p + s.ee_link, s.name)]),
        ee_body=_body_id(model, p + s.ee_link, s.name),
        hand_site=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{p}hand"),
        handle_site=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, names["grasp"]),
        ft_site=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{p}ft"),
        weld=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, names["grasp"]),
        force_adr=int(model.sensor_adr[sensor_f]),
        torque_adr=int(model.sensor_adr[sensor_t]),
        tool_mass=names["tool"][0],
        tool_com=np.asarray(names["tool"][1], dtype=float),
        effort_limit=limit,
        replaced_meshes=tuple(names["meshes"]),
        base_model=names["model"],
    )


def set_state(scene: Scene, cart_pose: Sequence[float] | np.ndarray, cart_z: float, xs: Sequence[np.ndarray]) -> None:
    """Reset the data: the cart at `cart_pose`, robot i's base and arm at ``xs[i]``; forward kinematics."""
    m, d = scene.model, scene.data
    mujoco.mj_resetData(m, d)
    c = scene.cart_qpos
    d.qpos[c : c + 3] = (cart_pose[0], cart_pose[1], cart_z)
    d.qpos[c + 3 : c + 7] = yaw_quat(float(cart_pose[2]))
    for r, x in zip(scene.robots, xs):
        x = np.asarray(x, dtype=float)
        if r.base == "planar":
            d.qpos[r.base_qpos] = x[:3]
        else:
            z0 = float(d.qpos[r.base_qpos[2]])  # the URDF root's height (free joints start at the body's pose)
            d.qpos[r.base_qpos[:3]] = (x[0], x[1], z0)
            d.qpos[r.base_qpos[3:7]] = yaw_quat(float(x[2]))
        d.qpos[r.arm_qpos] = x[3:]
    mujoco.mj_forward(m, d)
