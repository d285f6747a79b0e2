"""One MuJoCo scene, composed with `mujoco.MjSpec`: the cart (and its floor), the robots from their URDFs, the grasps.

The cart comes as a spec whose root holds a body ``cart`` with a free joint (:mod:`.mujoco_cart` or a
cart file checked by :mod:`.cart_file`); it is the scene's root, so its options, defaults and floor
stay its own (a plane floor at z = 0 is added when it has none). Each robot is its URDF, imported with
``fusestatic`` off (MuJoCo would otherwise fuse every fixed link into the world: the Ridgeback + iiwa
would weigh 36 kg instead of 267), attached under the prefix ``r<i>/`` with:

- the base: an omnidirectional base gets a planar joint set (slide x, slide y, hinge z) under velocity
  servos (its mecanum rollers are not simulated); a differential base gets a free joint, sphere tyres
  on its driven wheels and casters (they touch the floor, nothing else of the robot collides), and
  velocity servos on its two wheel joints;
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
from dataclasses import dataclass, field
from collections.abc import Sequence

import mujoco
import numpy as np

from wholebody.errors import WholeBodyError


class SceneCompositionError(WholeBodyError):
    """A robot or cart that cannot be composed into a MuJoCo scene (missing frame, joint or body)."""


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
    #: differential drive wheels: kv (N m s/rad); force range = the wheel joint's effort limit
    wheel_kv: float = 60.0
    #: velocity-controlled arm joints: kv (N m s/rad); force range = the joint's effort limit
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


def _urdf_spec(urdf: str) -> mujoco.MjSpec:
    """Return the robot's URDF as a spec with fixed links kept as bodies."""
    spec = mujoco.MjSpec.from_file(urdf)
    spec.compiler.fusestatic = False
    spec.compiler.discardvisual = True
    return spec


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


def sensor_placement(urdf: str, ee_link: str, ft_link: str, robot: str) -> tuple[str, np.ndarray, float, np.ndarray]:
    """Return (sensor body, F/T frame pose (4, 4) in it, tool mass, tool CoM in the F/T frame).

    The sensor body is the first body on the hand's chain beyond the F/T link (the F/T link itself when
    the hand is on it or it is the hand): MuJoCo's force sensor measures what that body's parent
    transmits to its subtree, i.e. the hand's load plus the tool beyond the sensor.
    """
    spec = _urdf_spec(urdf)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    ee, ft = _body_id(model, ee_link, robot), _body_id(model, ft_link, robot)
    ft_chain = set(_ancestors(model, ft))
    beyond = [b for b in _ancestors(model, ee) if b not in ft_chain]
    if beyond and int(model.body_parentid[beyond[-1]]) not in ft_chain:
        raise SceneCompositionError(f"robot {robot!r}: the hand {ee_link!r} is not beyond the F/T frame {ft_link!r}")
    sensor = beyond[-1] if beyond else ft
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


def _disable_collisions(spec: mujoco.MjSpec) -> None:
    for g in spec.geoms:
        if not g.name.endswith("_tyre"):
            g.contype = 0
            g.conaffinity = 0


def _add_tyres(spec: mujoco.MjSpec, setup: RobotSetup, floor: tuple[int, int]) -> list[str]:
    """Add a sphere tyre (the wheel's radius) to every wheel and caster wheel body; return the driven wheels' bodies."""
    driven = []
    model = spec.compile()
    for j in range(model.njnt):
        jname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        body = int(model.jnt_bodyid[j])
        bname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)
        is_driven = jname in setup.wheel_joints
        is_caster_wheel = "caster" in jname and "wheel" in jname
        if not (is_driven or is_caster_wheel):
            continue
        geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]
        cyl = [g for g in geoms if int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_CYLINDER)]
        if not cyl:
            raise SceneCompositionError(f"robot {setup.name!r}: wheel {jname!r} has no cylinder to roll on")
        radius = float(model.geom_size[cyl[0]][0])
        spec.body(bname).add_geom(
            name=f"{bname}_tyre",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[radius, 0, 0],
            mass=0.0,
            contype=floor[1],
            conaffinity=floor[0],
            condim=3,
            friction=[1.0, 0.005, 0.0001],
        )
        if is_driven:
            driven.append(bname)
    return driven


def _floor_bits(scene: mujoco.MjSpec) -> tuple[int, int]:
    """Return (contype, conaffinity) of the scene's floor plane; add one at z = 0 if there is none."""
    for g in scene.worldbody.geoms:
        if g.type == mujoco.mjtGeom.mjGEOM_PLANE:
            return int(g.contype), int(g.conaffinity)
    scene.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], contype=1, conaffinity=1)
    return 1, 1


def _prepare_robot(scene: mujoco.MjSpec, setup: RobotSetup, i: int, floor: tuple[int, int]) -> dict:
    """Attach robot `i` to the scene (joints, tyres, sensor site, hand site); return the names to index later."""
    prefix = f"r{i}/"
    spec = _urdf_spec(setup.urdf)
    root = spec.worldbody.first_body()
    if root is None:
        raise SceneCompositionError(f"robot {setup.name!r}: its URDF has no link")
    driven: list[str] = []
    if setup.base == "planar":
        root.add_joint(name="base_x", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0])
        root.add_joint(name="base_y", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 1, 0])
        root.add_joint(name="base_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
        base = "planar"
    elif setup.base == "differential":
        driven = _add_tyres(spec, setup, floor)
        root.add_freejoint(name="base_free")
        base = "differential"
    else:
        raise SceneCompositionError(f"robot {setup.name!r}: base {setup.base!r} is neither 'planar' nor 'differential'")
    _disable_collisions(spec)  # after the tyres were sized from the wheels' collision cylinders
    spec.compiler.discardvisual = False  # keep the (now collision-free) shapes for viewers
    sensor_body, T_sf, tool_mass, tool_com = sensor_placement(setup.urdf, setup.ee_link, setup.ft_link, setup.name)
    spec.body(sensor_body).add_site(name="ft", pos=T_sf[:3, 3], quat=quat_from_matrix(T_sf[:3, :3]), size=[0.01, 0, 0])
    spec.body(setup.ee_link).add_site(name="hand", size=[0.01, 0, 0])
    frame = scene.worldbody.add_frame()
    scene.attach(spec, prefix=prefix, frame=frame)
    return {"prefix": prefix, "base": base, "driven": driven, "tool": (tool_mass, tool_com)}


def _add_robot_elements(
    scene: mujoco.MjSpec,
    setup: RobotSetup,
    names: dict,
    i: int,
    compliance: GraspCompliance,
    gains: ServoGains,
    robot_inertia: tuple[float, float],
) -> None:
    """Add the grasp weld, the servos/motors and the F/T sensors of robot `i` (after attaching it)."""
    p = names["prefix"]
    T = setup.T_b_hand
    scene.body("cart").add_site(name=f"grasp{i}", pos=T[:3, 3], quat=quat_from_matrix(T[:3, :3]), size=[0.012, 0, 0])
    scene.add_equality(
        name=f"grasp{i}",
        type=mujoco.mjtEq.mjEQ_WELD,
        objtype=mujoco.mjtObj.mjOBJ_SITE,
        name1=f"{p}hand",
        name2=f"grasp{i}",
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


def robot_inertia(urdf: str) -> tuple[float, float]:
    """Return (mass, yaw inertia about the root link's origin) of a robot at its zero configuration."""
    from wholebody.push.mujoco_cart import composite_inertia

    model = _urdf_spec(urdf).compile()
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
    floor = _floor_bits(scene)
    names = [_prepare_robot(scene, s, i, floor) for i, s in enumerate(setups)]
    for i, (s, n) in enumerate(zip(setups, names)):
        _add_robot_elements(scene, s, n, i, compliance, gains, robot_inertia(s.urdf))
    try:
        model = scene.compile()
    except ValueError as exc:  # MuJoCo's compiler error
        raise SceneCompositionError(f"the MuJoCo scene does not compile: {str(exc).splitlines()[0]}") from None
    data = mujoco.MjData(model)
    cart = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "cart")
    cart_jnt = int(model.body_jntadr[cart])
    out = Scene(model, data, cart, int(model.jnt_qposadr[cart_jnt]), int(model.jnt_dofadr[cart_jnt]), [])
    out.robots = [_index(model, s, n, i) for i, (s, n) in enumerate(zip(setups, names))]
    set_state(out, cart_pose, cart_z, [s.x for s in setups])
    return out


def _jid(model: mujoco.MjModel, name: str) -> int:
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if j < 0:
        raise SceneCompositionError(f"no joint {name!r} in the scene")
    return j


def _aid(model: mujoco.MjModel, name: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)


def _index(model: mujoco.MjModel, s: RobotSetup, names: dict, i: int) -> RobotIndex:
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
    radius = 0.0
    if wheel_j:
        tyre = mujoco.mj_name2id(
            model,
            mujoco.mjtObj.mjOBJ_GEOM,
            f"{mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(wheel_bodies[0]))}_tyre",
        )
        radius = float(model.geom_size[tyre][0]) if tyre >= 0 else 0.0
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
        handle_site=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"grasp{i}"),
        ft_site=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{p}ft"),
        weld=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, f"grasp{i}"),
        force_adr=int(model.sensor_adr[sensor_f]),
        torque_adr=int(model.sensor_adr[sensor_t]),
        tool_mass=names["tool"][0],
        tool_com=np.asarray(names["tool"][1], dtype=float),
        effort_limit=limit,
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
