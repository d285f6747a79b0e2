"""The MuJoCo plant: robots and cart in a physics engine, behind the plant seam (`wholebody.push.plant`).

One scene (`wholebody.push.mujoco_scene`): the cart (the shopping cart built from `CartParams`, a
`MujocoCart`, or any cart file that follows the contract of `wholebody.push.cart_file`), a floor, the
robots from their URDFs and one compliant weld per grasp. Physics runs at ``physics_dt`` (500 Hz by
default), control at ``control_dt`` (100 Hz): each :meth:`MujocoPlant.step` holds one command per robot
for one control period:

- bases: a holonomic base (the Ridgeback) follows the commanded body twist on velocity servos of a
  planar joint set (its mecanum rollers are not simulated); a differential base (the WMRA) drives its
  two wheels on velocity servos at the commanded wheel rates, on tyres in contact with the floor with
  its casters: its nonholonomic constraint and its wheel slip are physical (the largest slip speed is
  reported);
- arms: `wholebody.push.arm_control` (torque law for a torque-controlled arm, admittance around
  velocity servos for a velocity-controlled one); a torque-controlled arm's force loop also gets, every physics
  step, its external joint torque (joint torques, accelerations and the model: :meth:`MujocoPlant._joint_samples`);
- sensing (:meth:`MujocoPlant.measure`): motion capture of the ``cart`` body (with the noise model of
  the kinematic plant, `cart.simulate.MeasurementNoise`), joint and base states, and each wrist F/T
  sensor (MuJoCo force and torque sensors at the F/T frame, the static load of the tool beyond the
  sensor removed as a real sensor's tool compensation does, plus white noise).

:meth:`report` gives the run's diagnostics (``cart_mass_kg``, ``cart_mass_effective_kg``,
``wrench_error_rms_n`` (the period-mean hand force minus the allocated one), ``grasp_slip_max_m``,
``base_wheel_slip_max_m_s``, ``real_time_factor``, ...).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field, replace
from collections.abc import Sequence

import mujoco
import numpy as np

from cart.params import CartParams
from cart.simulate import MeasurementNoise
from wholebody.errors import WholeBodyError
from wholebody.push import mujoco_cart
from wholebody.push.admittance_tuning import arm_tuning, set_servo_damping
from wholebody.push.admittance_law import AdmittanceArmLaw, AdmittanceGains
from wholebody.push.arm_control import (
    TorqueArmGains,
    TorqueArmLaw,
    hand_inertia_terms,
    net_wrench_projector,
)
from wholebody.push.config import PUSH_SENSOR_NOISE, TRUE_CART
from wholebody.push.load_change import LoadChange, check_changes
from wholebody.push.mujoco_scene import (
    ARM_TORQUE,
    ARM_VELOCITY,
    GraspCompliance,
    RobotIndex,
    RobotSetup,
    Scene,
    ServoGains,
    compose,
)
from wholebody.push.plant import Measurement, RobotCommand, RobotReading

#: How each shipped robot's arm is driven: joint torques (the iiwa) or joint velocity servos (the WMRA's).
#: Robots not listed get velocity servos (any position/velocity-servoed arm).
ARM_MODES = {"ridgeback_iiwa": ARM_TORQUE, "wmra": ARM_VELOCITY}
#: velocity-servo arms whose admittance gains were tuned for them (`AdmittanceGains` as given, `from_arm` ignored):
#: none; every velocity-servoed arm, the WMRA's among them, takes its servos' damping from its limits
#: (`admittance_tuning.arm_tuning`)
TUNED_ADMITTANCE: frozenset[str] = frozenset()
GRAVITY_VECTOR = np.array([0.0, 0.0, -mujoco_cart.GRAVITY])
#: the constraint types whose forces are the joints' own (dof friction, joint limits), as ints: a numpy array
#: compared with MuJoCo's enum objects compares element by element in Python (about 1 ms per physics step)
_SITE = mujoco.mjtObj.mjOBJ_SITE
#: after the settle the cart stands: {b} within this height (m) of where it started and this tilt (deg) of level
STANDING_DROP_M = 0.05
#: a cart heavier than this (kg) that does not stand after the settle is said to sink or tip on its soft contacts
HEAVY_CART_KG = 1000.0
STANDING_TILT_DEG = 10.0
_JOINT_INTERNAL = (int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF), int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT))


def arm_mode_of(mm) -> str:
    """Return how a robot's arm is driven: its profile's ``arm_control`` if it has one, else `ARM_MODES` by name."""
    mode = getattr(mm.profile, "arm_control", None)
    return str(mode) if mode else ARM_MODES.get(mm.wb.robot.name, ARM_VELOCITY)


class MujocoPlantError(WholeBodyError):
    """Bad input to the MuJoCo plant (command count or shape, grasp not on a handle, unknown arm mode)."""


@dataclass(frozen=True)
class JointTorqueNoise:
    """Errors of a torque-sensing arm's external joint torque (`MujocoPlant._joint_samples`), per joint, as
    fractions of the joint's effort limit: white noise on every physics step's sample and an offset drawn once per
    run (a strain-gauge joint torque sensor's noise and its zero and model error; the engine's torques are exact).

    Assumed, not measured on an arm: 0.1 % and 1 % of the limit (the iiwa's first joint: 0.32 and 3.2 N m).
    """

    white: float = 0.001
    offset: float = 0.01


@dataclass(frozen=True)
class MujocoPlantConfig:
    """Rates, grasp compliance, servo gains and arm laws of the MuJoCo plant."""

    physics_dt: float = 0.002
    control_dt: float = 0.01
    compliance: GraspCompliance = GraspCompliance()
    servos: ServoGains = ServoGains()
    torque_gains: TorqueArmGains = TorqueArmGains()
    admittance: AdmittanceGains = AdmittanceGains()
    #: largest distance (m) between a grasp and the handle sites for the grasp to count as on the handle
    handle_tolerance: float = 0.02
    #: time (s) the scene settles (wheels onto the floor, casters, grasp) before t = 0, robots holding still
    settle_time: float = 0.2
    #: the errors of the torque-controlled arms' external joint torque (`JointTorqueNoise`; zeros: exact)
    joint_torque_noise: JointTorqueNoise = JointTorqueNoise()
    #: the force loops of two or more torque-controlled arms on one cart: "full" (each arm on its own error), "net"
    #: (the loops close on the stacked error's part in the cart's net wrench, `arm_control.net_wrench_projector`; the
    #: squeeze between the hands, which no cart motion shows, is left to the feed-forward) or "off" (open-loop
    #: ``J^T w``). Measured (two Ridgeback + iiwa, `cartpush push --plant mujoco --arms 2 --json`, seeds 0/1;
    #: docs/mujoco.md "Several arms on one cart"): "full" Traj. 2 seed 0 2.89 mm, wrench error 7.8 % of the hand
    #: force with the default `TorqueArmGains`; "off" Traj. 2 seed 0 17.6 mm, 74 % without the arm inertia fed forward (the arms' task-space inertia, 19
    #: kg along the push at the iiwa's push posture, takes the push). The loops need each base held at its place
    #: (`BasePlanSettings.base_weight`): with a base that lags its place the loops make the cart follow its
    #: reference while the hand reaches further from that base, and an elbow comes through straight (the squeeze
    #: then is the stretched arm's)
    multi_arm_force_loop: str = "full"
    #: the torque-controlled arms' force loops zero their sensors while the scene settles (`settle_time`, the robots
    #: holding still): the slow parts of the joint torque sensing and of the F/T's correction (`TorqueArmLaw.hold`,
    #: `TorqueArmLaw.tare`) start the push from those samples, not from its first ones
    tare: bool = True

    def __post_init__(self) -> None:
        if self.multi_arm_force_loop not in ("net", "full", "off"):
            raise MujocoPlantError(
                f"multi_arm_force_loop must be 'net', 'full' or 'off', got {self.multi_arm_force_loop!r}"
            )
        if not (0 < self.physics_dt <= self.control_dt):
            raise MujocoPlantError(f"need 0 < physics_dt <= control_dt, got {self.physics_dt}, {self.control_dt}")
        ratio = self.control_dt / self.physics_dt
        if abs(ratio - round(ratio)) > 1e-9:
            raise MujocoPlantError(
                f"control_dt must be a multiple of physics_dt, got {self.control_dt}/{self.physics_dt}"
            )


@dataclass(frozen=True)
class CartInertial:
    """The cart's rigid-body truth read from MuJoCo (for reports; a controller never reads it)."""

    mass: float
    #: (dx, dy) centre of mass in {b}
    com_b: tuple[float, float]
    #: yaw inertia about the centre of mass (kg m^2)
    inertia: float
    #: mass the forward motion feels: mass + sum of wheel spin inertia / r^2 (kg)
    mass_effective: float


@dataclass
class _Stats:
    """Running diagnostics of a run."""

    slip_max: float = 0.0
    wheel_slip_max: float = 0.0
    err_sq: float = 0.0
    #: the hand force error's part in the cart's net wrench and in the squeeze between the hands (several arms)
    err_net_sq: float = 0.0
    err_internal_sq: float = 0.0
    force_sq: float = 0.0
    n: int = 0
    wall: float = 0.0
    sim: float = 0.0
    arm_force_peak_ratio: float = 0.0
    arm_saturated: int = 0
    #: torque-controlled arms: the peak of the law's task part (J^T w + b) / limit, steps whose feedback the torque
    #: budget scaled down, and per robot the peak request / limit of each joint
    arm_task_peak_ratio: float = 0.0
    arm_scaled: int = 0
    joint_peak_ratio: dict = field(default_factory=dict)
    per_robot_err: list = field(default_factory=list)
    #: the cart body's largest tilt (deg) from upright, and when it first passed `STANDING_TILT_DEG` (None: never)
    cart_tilt_max_deg: float = 0.0
    cart_tipped_at_s: float | None = None


def _robot_setup(mm, T_b_hand: np.ndarray, arm_mode: str) -> RobotSetup:
    """Return the scene's view of a `MobileManipulator` (URDF, joints, frames, initial state)."""
    prof = mm.profile
    frames = mm.model.frames
    return RobotSetup(
        name=mm.wb.robot.name,
        urdf=str(mm.wb.robot.urdf),
        base="differential" if prof.base == "differential" else "planar",
        arm_joints=tuple(prof.arm_joints),
        wheel_joints=tuple(prof.wheel_joints),
        x=np.array(mm.x, dtype=float),
        arm_mode=arm_mode,
        ee_link=frames[mm.ee_id].name,
        ft_link=frames[mm.ft_id].name,
        T_b_hand=T_b_hand,
        package_dirs=tuple(str(d) for d in prof.package_dirs),
        locked=tuple(prof.locked),
    )


def _planar(T: np.ndarray) -> tuple[float, float, float]:
    return float(T[0, 3]), float(T[1, 3]), math.atan2(T[1, 0], T[0, 0])


def _pose_matrix(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = (x, y, z)
    return T


class MujocoPlant:
    """Robots and cart in MuJoCo, answering a push controller one control period at a time (see the module doc).

    Args:
        robots: the mobile manipulators (`wholebody.push.robot.MobileManipulator`), each in its initial
            state ``x`` = [base pose, arm joints] holding the handle; only read here (URDF, profile,
            frames, ``x``).
        cart_pose: (x, y, theta) of {b} at the start.
        cart: `CartParams` (the shopping cart with these inertial parameters, `mujoco_cart.shopping_cart`),
            a `mujoco_cart.MujocoCart`, or the path of an MJCF cart file (`wholebody.push.cart_file`).
        grasp_points_b: (n_robots, 3) grasp points in {b}; each must be within
            ``config.handle_tolerance`` of the robot's hand and of a handle site. None: the hands' points.
        noise: white noise of motion capture and F/T sensors (`cart.simulate.MeasurementNoise`).
        seed: seed of the noise.
        config: rates, compliance, gains (`MujocoPlantConfig`).
        arm_modes: "torque" or "velocity" per robot; None: `ARM_MODES` by robot name.
        load_changes: loads put in or taken out (`wholebody.push.load_change`), each at the first control period
            starting at or after its time (:meth:`_apply_load_changes`).
    """

    def __init__(
        self,
        robots: Sequence,
        cart_pose: Sequence[float] | np.ndarray,
        cart: CartParams | mujoco_cart.MujocoCart | str | os.PathLike = TRUE_CART,
        grasp_points_b: Sequence[Sequence[float]] | None = None,
        noise: MeasurementNoise = PUSH_SENSOR_NOISE,
        seed: int = 0,
        config: MujocoPlantConfig = MujocoPlantConfig(),
        arm_modes: Sequence[str] | None = None,
        load_changes: Sequence[LoadChange] = (),
    ) -> None:
        from wholebody.push.cart_file import CartSource, cart_source

        self.config = config
        self.dt = float(config.control_dt)
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        #: the F/T noise of the arms' force loops (every physics step), apart from the sensing's
        self._rng_loop = np.random.default_rng([0 if seed is None else seed, 1])
        #: the joint torque sensing's noise (every physics step), apart from the F/T's
        self._rng_joint = np.random.default_rng([0 if seed is None else seed, 2])
        #: the same two noises while the scene settles (`MujocoPlantConfig.tare`), apart from the push's: the push
        #: draws the same noise with or without the tare
        self._rng_settle = [np.random.default_rng([0 if seed is None else seed, k]) for k in (3, 4)]
        self.n_sub = int(round(config.control_dt / config.physics_dt))
        robots = list(robots)
        modes = list(arm_modes) if arm_modes is not None else [arm_mode_of(mm) for mm in robots]
        if len(modes) != len(robots) or any(m not in (ARM_TORQUE, ARM_VELOCITY) for m in modes):
            raise MujocoPlantError(f"arm_modes must give 'torque' or 'velocity' per robot, got {modes}")
        source: CartSource = cart_source(cart)
        self.cart_source = source
        T_sb = _pose_matrix(cart_pose[0], cart_pose[1], source.z, cart_pose[2])
        hands_b = [np.linalg.inv(T_sb) @ mm.wb.ee_placement(mm.x).homogeneous for mm in robots]
        self._check_grasps(hands_b, grasp_points_b, source)
        setups = [_robot_setup(mm, T, mode) for mm, T, mode in zip(robots, hands_b, modes)]
        self.scene: Scene = compose(
            source.spec(), cart_pose, source.z, setups, config.physics_dt, config.compliance, config.servos
        )
        self._robots = robots
        self._setups = setups
        self._laws = self._arm_laws(setups)
        #: per robot: (white noise std, offset) of its external joint torque, N m per joint
        self._joint_noise = self._draw_joint_noise()
        self._init_buffers(len(robots), float(cart_pose[2]))
        self._pending = sorted(load_changes, key=lambda c: c.t)
        self._start()
        #: [(time it took effect, the cart's inertial truth from then on)], the first at t = 0
        self.inertial_log: list[tuple[float, CartInertial]] = [(0.0, self._inertial)]
        i0 = self._inertial
        check_changes(CartParams(i0.mass, *i0.com_b, i0.inertia), self._pending, math.inf)
        self._check_cart_body_holds()

    def _check_cart_body_holds(self) -> None:
        """Raise `MujocoPlantError` before the run when a load change takes out more than the cart body holds, or
        leaves it no rigid inertia: the changes are applied to the ``cart`` body alone (bodies welded to it keep
        their mass). The changes are tried in turn on the body's inertial, which is then restored."""
        m, cart = self.scene.model, self.scene.cart_body
        saved = [np.array(a[cart], copy=True) for a in (m.body_mass, m.body_ipos, m.body_iquat, m.body_inertia)]
        try:
            for change in self._pending:
                x, y = change.xy if change.xy is not None else m.body_ipos[cart][:2]
                held = float(m.body_mass[cart])
                try:
                    mujoco_cart.add_point_mass(m, cart, change.mass, (x, y, float(m.body_ipos[cart][2])))
                except mujoco_cart.CartModelError:
                    raise MujocoPlantError(
                        f"the load change at t = {change.t:g} s takes out {-change.mass:g} kg at ({x:.3f}, {y:.3f}) m, "
                        f"but the MuJoCo cart's body 'cart' holds {held:.3g} kg of the cart's "
                        f"{self._inertial.mass:.3g} kg (loads are put in and taken out of the body 'cart'; bodies "
                        "welded or attached to it keep their mass): take out less, or nearer its centre of mass "
                        f"({float(m.body_ipos[cart][0]):.3f}, {float(m.body_ipos[cart][1]):.3f}) m"
                    ) from None
        finally:
            for a, v in zip((m.body_mass, m.body_ipos, m.body_iquat, m.body_inertia), saved):
                a[cart] = v

    def _init_buffers(self, n_robots: int, theta0: float) -> None:
        """Allocate the per-step work arrays and the run's statistics (after the scene and the setups exist)."""
        nv = self.scene.model.nv
        self._qacc = np.zeros(nv)
        self._quat = np.zeros(4)
        self._vel6 = np.zeros(6)
        self._site_acc, self._site_vel = np.zeros(6), np.zeros(6)
        m = self.scene.model
        #: per robot: the body its arm is mounted on (the parent of its first arm joint's body)
        self._mount_body = [int(m.body_parentid[m.dof_bodyid[r.arm_dof[0]]]) for r in self.scene.robots]
        #: per robot (by prefix): the index tuples of the joint inertia's arm-arm and arm-base blocks
        self._blocks = {
            r.prefix: (np.ix_(r.arm_dof, r.arm_dof), np.ix_(r.arm_dof, r.base_dof)) for r in self.scene.robots
        }
        self._target_prev: list[np.ndarray | None] = [None] * n_robots
        self._rne = np.zeros(nv)
        self._mdv = np.zeros(nv)
        self._joint_frc = np.zeros(nv)
        self._stats = _Stats(per_robot_err=[[0.0, 0.0] for _ in range(n_robots)])
        self._theta_prev = theta0
        self._theta = theta0
        self._base_yaw = [float(s.x[2]) for s in self._setups]
        self._yaw_prev = list(self._base_yaw)
        self._hand_clean = [np.zeros(6) for _ in range(n_robots)]
        self._hand_sum = [np.zeros(6) for _ in range(n_robots)]
        #: each hand's `_sensor_wrench` at the state of the last physics step of `step` (None: not read at this state)
        self._clean: list[np.ndarray] | None = None
        self._base_int = [np.zeros(3) for _ in range(n_robots)]
        #: the force rows of the robots' stacked wrenches (`_split_error`)
        self._force_rows = np.array([6 * i + k for i in range(n_robots) for k in range(3)])
        #: the F/T noise's standard deviations per axis (force, torque)
        self._ft_std = np.repeat([self.noise.force, self.noise.torque], 3).astype(float)

    def _draw_joint_noise(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Return each robot's joint torque sensing noise: (white std per step, offset drawn once), N m per joint."""
        jn = self.config.joint_torque_noise
        return [
            (
                jn.white * r.effort_limit,
                self._rng_joint.normal(0.0, 1.0, r.effort_limit.size) * jn.offset * r.effort_limit,
            )
            for r in self.scene.robots
        ]

    def _start(self) -> None:
        """Settle the scene, read the cart's inertial truth and take the first F/T and motion-capture readings."""
        self._settle()
        self._check_standing()
        self._inertial = self._read_inertial()
        self.t = 0.0
        self.scene.data.time = 0.0
        #: the cart's own joints (casters, wheels) and each robot's, from t = 0 once per control period, for the page
        self.cart_joints = mujoco_cart.CartJointRecord.of(self.scene.model)
        self.robot_joints = [mujoco_cart.CartJointRecord.of(self.scene.model, r.root_body) for r in self.scene.robots]
        for record in [self.cart_joints, *self.robot_joints]:
            record.record(0.0, self.scene.data)
        self._ft = [self._ft_reading(i, noisy=True) for i in range(len(self._robots))]
        self._z = self._motion_capture()

    # ------------------------------------------------------------------ set-up

    def _arm_laws(self, setups: Sequence[RobotSetup]) -> list[TorqueArmLaw | AdmittanceArmLaw]:
        """Return each arm's law (torque or admittance); several torque arms lose their F/T loops with
        `MujocoPlantConfig.multi_arm_force_loop` "off"."""
        config = self.config
        torque_gains = config.torque_gains
        admittance = config.admittance  # the push fed forward through the servos the scene builds (their k_v)
        if admittance.servo_kv is None:
            admittance = replace(admittance, servo_kv=config.servos.arm_kv)
        if sum(s.arm_mode == ARM_TORQUE for s in setups) > 1 and config.multi_arm_force_loop == "off":
            torque_gains = replace(torque_gains, force_feedback=0.0)
        laws: list[TorqueArmLaw | AdmittanceArmLaw] = []
        for mm, r, s in zip(self._robots, self.scene.robots, setups):
            if s.arm_mode == ARM_TORQUE:
                damping = np.asarray(mm.model.damping)[mm.wb.arm_idx_v]  # the robot model's (its URDF's)
                laws.append(TorqueArmLaw(r.effort_limit, torque_gains, config.physics_dt, damping))
                continue
            gains = admittance
            if gains.from_arm and mm.wb.robot.name not in TUNED_ADMITTANCE:  # damping and loop gain from the limits
                tuned = arm_tuning(r.effort_limit, mm.wb.arm_velocity_limit, config.servos.arm_kv, gains.loop_gain)
                set_servo_damping(self.scene.model, r.arm_actuators, tuned.kv)
                gains = replace(gains, servo_kv=tuple(float(k) for k in tuned.kv), loop_gain=tuned.loop_gain)
            laws.append(AdmittanceArmLaw(len(s.arm_joints), gains, r.effort_limit))
        return laws

    def _check_grasps(self, hands_b: list[np.ndarray], points: Sequence[Sequence[float]] | None, source) -> None:
        tol = self.config.handle_tolerance
        for i, T in enumerate(hands_b):
            p = T[:3, 3]
            if points is not None:
                if len(points) != len(hands_b):
                    raise MujocoPlantError(f"{len(points)} grasp points for {len(hands_b)} robots")
                gap = float(np.linalg.norm(np.asarray(points[i], dtype=float) - p))
                if gap > tol:
                    raise MujocoPlantError(
                        f"robot {i}'s hand is {gap:.3f} m from its grasp point {np.round(points[i], 3)}"
                    )
            dist, name = source.distance_to_handle(p)
            if dist > tol:
                raise MujocoPlantError(
                    f"robot {i}'s hand at {np.round(p, 3)} in {{b}} is {dist:.3f} m from the handle site {name!r}"
                )

    def _settle(self) -> None:
        """Let wheels, casters and grasps settle for `settle_time` with the robots holding still (MuJoCo's own bias)."""
        m, d = self.scene.model, self.scene.data
        tare = self._fused_loops() if self.config.tare else []
        push_rngs = self._rng_loop, self._rng_joint
        self._rng_loop, self._rng_joint = self._rng_settle
        for _ in range(int(round(self.config.settle_time / self.config.physics_dt))):
            for r, s in zip(self.scene.robots, self._setups):
                if s.arm_mode == ARM_TORQUE:
                    d.ctrl[r.arm_actuators] = d.qfrc_bias[r.arm_dof]
                else:
                    d.ctrl[r.arm_actuators] = 0.0
                    d.ctrl[r.arm_hold_actuators] = d.qfrc_bias[r.arm_dof]
                d.ctrl[r.base_actuators] = 0.0
                d.ctrl[r.wheel_actuators] = 0.0
            for i, (r, law) in tare:
                law.hold(self._arm_jacobian_inertia(r)[0], d.ctrl[r.arm_actuators], d.qvel[r.arm_dof])
            mujoco.mj_step(m, d)
            if tare:
                self._joint_samples()
                for i, (r, law) in tare:
                    law.tare(self._ft_at_grasp(i))
        self._rng_loop, self._rng_joint = push_rngs
        mujoco.mj_forward(m, d)

    def _check_standing(self) -> None:
        """Raise unless the cart still stands after the settle: {b} at its height and level (a floor or wheels that
        do not collide, contacts disabled or excluded, let it fall through or tip before the push)."""
        d, b = self.scene.data, self.scene.cart_body
        drop = float(self.cart_source.z - d.xpos[b][2])
        tilt = self._cart_tilt_deg()
        if abs(drop) > STANDING_DROP_M or tilt > STANDING_TILT_DEG:
            mass = self.cart_source.mass
            heavy = mass is not None and mass > HEAVY_CART_KG
            raise MujocoPlantError(
                f"cart {self.cart_source.label}: it does not stand on the floor after the "
                f"{self.config.settle_time:g} s settle ({{b}} {abs(drop):.2f} m {'below' if drop > 0 else 'above'} "
                f"its start, tilted {tilt:.0f} deg): "
                + (
                    f"at {mass:.4g} kg it sinks or tips on its wheels' soft contacts; check its masses (kg), or stiffen the "
                    "wheels' contacts (solref) for a load that heavy"
                    if heavy
                    else "check that its wheels and the floor collide (contype/conaffinity, <contact><exclude>, "
                    "<option><flag contact>) and that it rests on its wheels"
                )
            )

    def _fused_loops(self) -> list[tuple[int, tuple[RobotIndex, TorqueArmLaw]]]:
        """Return (index, (robot, law)) of each torque law whose force loop fuses the joint torques with the F/T
        (found once: the laws and their gains are fixed)."""
        fused = getattr(self, "_fused", None)
        if fused is None:
            fused = self._fused = [
                (i, (r, law))
                for i, (r, law) in enumerate(zip(self.scene.robots, self._laws))
                if isinstance(law, TorqueArmLaw) and law.gains.fusion_tau > 0.0 and law.gains.force_feedback > 0.0
            ]
        return fused

    def _loop_laws(self) -> list[tuple[int, TorqueArmLaw]]:
        """Return (index, law) of each torque law with a force loop (found once: the laws and their gains are fixed)."""
        loops = getattr(self, "_loops", None)
        if loops is None:
            loops = self._loops = [
                (i, law)
                for i, law in enumerate(self._laws)
                if isinstance(law, TorqueArmLaw) and law.gains.force_feedback > 0.0
            ]
        return loops

    def _read_inertial(self) -> CartInertial:
        m, d = self.scene.model, self.scene.data
        robots = [r.root_body for r in self.scene.robots]
        loads = mujoco_cart.welded_loads(m, d, self.scene.cart_body, exclude=robots)
        info = mujoco_cart.truth_from_state(m, d, mujoco_cart.CART_BODY, self.cart_source.wheels(m, d), loads)
        return CartInertial(
            info["m"], (info["dx"], info["dy"]), info["I_about_com"], info["m_effective_forward_incl_wheel_spin"]
        )

    # ------------------------------------------------------------------ truth

    def cart_inertial(self) -> CartInertial:
        """Return the cart's mass, CoM in {b}, yaw inertia about the CoM and effective forward mass (truth only)."""
        return self._inertial

    def cart_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the true cart pose (x, y, theta unwrapped) and velocity (xdot, ydot, thetadot) of {b} in {s}."""
        d, b, dof = self.scene.data, self.scene.cart_body, self.scene.cart_dof
        x, y = float(d.xpos[b][0]), float(d.xpos[b][1])
        R = d.xmat[b].reshape(3, 3)
        omega = float((R @ d.qvel[dof + 3 : dof + 6])[2])
        return np.array([x, y, self._theta]), np.array([float(d.qvel[dof]), float(d.qvel[dof + 1]), omega])

    truth = cart_state

    def robot_states(self) -> list[np.ndarray]:
        """Return the true robot states x = [base pose, arm joints]."""
        d = self.scene.data
        return [np.concatenate((self._base_pose(i), d.qpos[r.arm_qpos])) for i, r in enumerate(self.scene.robots)]

    def cart_wrench(self, commands: Sequence[RobotCommand] | None = None) -> np.ndarray:
        """Return Gamma_MM (fx, fy in {s}, tau about the {b} origin) the hands applied over the last period (clean F/T).

        ``commands`` is ignored: the wrench is what the physics made of the last commands.
        """
        d = self.scene.data
        ob = d.xpos[self.scene.cart_body]
        gamma = np.zeros(3)
        for r, w in zip(self.scene.robots, self._hand_clean):
            p = d.site_xpos[r.handle_site]
            gamma += np.array([w[0], w[1], w[5] + (p[0] - ob[0]) * w[1] - (p[1] - ob[1]) * w[0]])
        return gamma

    # ------------------------------------------------------------------ sensing

    def _base_pose(self, i: int) -> np.ndarray:
        r, d = self.scene.robots[i], self.scene.data
        if r.base == "planar":
            return d.qpos[r.base_qpos].copy()
        b = r.root_body
        return np.array([float(d.xpos[b][0]), float(d.xpos[b][1]), self._base_yaw[i]])

    def _base_twist(self, i: int) -> np.ndarray:
        r, d = self.scene.robots[i], self.scene.data
        if r.base == "planar":
            v = d.qvel[r.base_dof]
            c, s = math.cos(d.qpos[r.base_qpos[2]]), math.sin(d.qpos[r.base_qpos[2]])
            return np.array([c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]])
        R = d.xmat[r.root_body].reshape(3, 3)
        v_w = d.qvel[r.base_dof[:3]]
        w_w = R @ d.qvel[r.base_dof[3:]]
        v_b = R.T @ v_w
        return np.array([v_b[0], v_b[1], w_w[2]])

    def _sensor_wrench(self, i: int) -> np.ndarray:
        """Return the hand's wrench on the cart in the F/T frame, about its origin (tool load removed), no noise."""
        r, d = self.scene.robots[i], self.scene.data
        f0, f1, f2 = d.sensordata[r.force_adr : r.force_adr + 3].tolist()
        n0, n1, n2 = d.sensordata[r.torque_adr : r.torque_adr + 3].tolist()
        R = d.site_xmat[r.ft_site].reshape(3, 3)
        g_s = R.T @ (r.tool_mass * self._tool_proper_acceleration(i))  # the tool's load in the sensor frame
        gx, gy, gz = g_s.tolist()
        cx, cy, cz = r.tool_com.tolist()
        # MuJoCo senses what the child subtree applies to its parent: the hand's push on the cart, minus the
        # tool's load (F_sensor = w_hand - m (g - a): its weight and its inertia), and likewise for the torque
        # (3-vectors as Python floats: the same arithmetic as numpy's, without its per-call cost)
        return np.array(
            [f0 + gx, f1 + gy, f2 + gz, n0 + (cy * gz - cz * gy), n1 + (cz * gx - cx * gz), n2 + (cx * gy - cy * gx)]
        )

    def _tool_proper_acceleration(self, i: int) -> np.ndarray:
        """Return g - a of the tool's centre of mass (world, m/s^2): gravity less its acceleration (the tool rides on
        the handle, so a is the handle's; read from MuJoCo's body accelerations of this step)."""
        r, m, d = self.scene.robots[i], self.scene.model, self.scene.data
        acc, vel = self._site_acc, self._site_vel
        mujoco.mj_objectAcceleration(m, d, _SITE, r.ft_site, acc, 0)
        mujoco.mj_objectVelocity(m, d, _SITE, r.ft_site, vel, 0)
        rx, ry, rz = (d.site_xmat[r.ft_site].reshape(3, 3) @ r.tool_com).tolist()
        ax, ay, az, lx, ly, lz = acc.tolist()
        wx, wy, wz = vel[:3].tolist()
        vx, vy, vz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx  # w x rho
        # MuJoCo's accelerations carry -g (an accelerometer's reading): acc[3:] = a_site - g;
        # g - a = -(acc[3:] + alpha x rho + w x (w x rho))
        return -np.array(
            [
                lx + (ay * rz - az * ry) + (wy * vz - wz * vy),
                ly + (az * rx - ax * rz) + (wz * vx - wx * vz),
                lz + (ax * ry - ay * rx) + (wx * vy - wy * vx),
            ]
        )

    def _hand_wrench_world(self, i: int, w_s: np.ndarray) -> np.ndarray:
        """Return a sensor-frame wrench as world-aligned [f, n] at the grasp (the hand's site)."""
        r, d = self.scene.robots[i], self.scene.data
        R = d.site_xmat[r.ft_site].reshape(3, 3)
        f, n = R @ w_s[:3], R @ w_s[3:]
        ox, oy, oz = d.site_xpos[r.ft_site].tolist()
        px, py, pz = d.site_xpos[r.hand_site].tolist()
        rx, ry, rz = ox - px, oy - py, oz - pz
        fx, fy, fz = f.tolist()
        n0, n1, n2 = n.tolist()
        return np.array([fx, fy, fz, n0 + (ry * fz - rz * fy), n1 + (rz * fx - rx * fz), n2 + (rx * fy - ry * fx)])

    def _ft_at_grasp(self, i: int) -> np.ndarray:
        """Return the F/T sensor's reading of this physics step (with its noise) as the hand's wrench at the grasp."""
        # the draws of normal(0, force, 3) then normal(0, torque, 3)
        noise = self._rng_loop.standard_normal(6) * self._ft_std
        return self._hand_wrench_world(i, self._clean_wrench(i) + noise)

    def _force_loops(self) -> dict[int, np.ndarray]:
        """Return each torque law's force loop wrench of this physics step (robot index -> wrench, world-aligned at
        the grasp; `TorqueArmLaw.force_loop` of `TorqueArmLaw.force_error` of the F/T reading).

        With several loops on the cart and `MujocoPlantConfig.multi_arm_force_loop` "net" both the stacked error
        and the stacked loop wrench are projected onto the cart's net wrench (`net_wrench_projector` at the grasps):
        each loop drives the net wrench's error to zero, none integrates along the squeeze between the hands, and
        the loops' gains (forces and moments differ) put no squeeze into the push.
        """
        loop_laws = self._loop_laws()
        errors = [law.force_error(self._ft_at_grasp(i)) for i, law in loop_laws]
        if len(loop_laws) < 2 or self.config.multi_arm_force_loop != "net":
            return {i: law.force_loop(e) for (i, law), e in zip(loop_laws, errors)}
        loops = [i for i, _ in loop_laws]
        P = self._net_projector(loops)
        e = P @ np.concatenate(errors)
        u = P @ np.concatenate([law.force_loop(e[6 * k : 6 * k + 6]) for k, (_, law) in enumerate(loop_laws)])
        return {i: u[6 * k : 6 * k + 6] for k, i in enumerate(loops)}

    def _net_projector(self, robots: Sequence[int]) -> np.ndarray:
        """Return `net_wrench_projector` at the grasps (hand sites) of `robots`, as they are now."""
        d = self.scene.data
        return net_wrench_projector(np.array([d.site_xpos[self.scene.robots[i].hand_site] for i in robots]))

    def _clean_wrench(self, i: int) -> np.ndarray:
        """Return `_sensor_wrench` of hand i, read once per physics step (`step` keeps it until the state moves)."""
        return self._sensor_wrench(i) if self._clean is None else self._clean[i]

    def _ft_reading(self, i: int, noisy: bool) -> np.ndarray:
        w = self._clean_wrench(i).copy()
        if noisy:
            w = w + np.concatenate(
                (self.rng.normal(0.0, self.noise.force, 3), self.rng.normal(0.0, self.noise.torque, 3))
            )
        return w

    def _motion_capture(self) -> np.ndarray:
        q, qd = self.cart_state()
        return np.concatenate((q, qd)) + self.rng.normal(0.0, 1.0, 6) * self.noise.measurement_std()

    def measure(self) -> Measurement:
        """Return motion capture of the cart, each robot's base/joint states and F/T reading, at the current instant."""
        d = self.scene.data
        readings = tuple(
            RobotReading(
                base_pose=self._base_pose(i),
                base_twist=self._base_twist(i),
                q_arm=d.qpos[r.arm_qpos].copy(),
                v_arm=d.qvel[r.arm_dof].copy(),
                ft=self._ft[i].copy(),
            )
            for i, r in enumerate(self.scene.robots)
        )
        return Measurement(self.t, self._z[:3].copy(), self._z[3:].copy(), readings)

    # ------------------------------------------------------------------ stepping

    def _site_jacobian_inertia(self, r: RobotIndex) -> tuple[np.ndarray, np.ndarray]:
        """Return the hand site's world-aligned Jacobian (6, nv) and the whole scene's joint inertia (nv, nv)."""
        m, d = self.scene.model, self.scene.data
        J = np.zeros((6, m.nv))
        mujoco.mj_jacSite(m, d, J[:3], J[3:], r.hand_site)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        return J, M

    def _arm_jacobian_inertia(
        self, r: RobotIndex, full: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the hand's world-aligned Jacobian (6, n_arm) at the hand site and the arm's joint inertia (of
        `full`, `_site_jacobian_inertia`'s, when given)."""
        J, M = self._site_jacobian_inertia(r) if full is None else full
        return J[:, r.arm_dof], M[self._blocks[r.prefix][0]]

    def _hand_inertia(
        self, r: RobotIndex, c: RobotCommand, full: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Return the arm's inertial terms under the command's predicted hand acceleration (`TorqueArmLaw.begin`:
        `arm_control.hand_inertia_terms` with the engine's inertia, Jacobians and the hand's ``Jdot qdot`` at the
        period's start, and the base joints' planned acceleration); None without a ``hand_acceleration`` of one hand.
        `full`: `_site_jacobian_inertia`'s, when the caller has it."""
        if c.hand_acceleration is None or np.shape(c.hand_acceleration) != (6,):
            return None
        m, d = self.scene.model, self.scene.data
        dotp, dotr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mujoco.mj_jacDot(m, d, dotp, dotr, d.site_xpos[r.hand_site], int(m.site_bodyid[r.hand_site]))
        J, M = self._site_jacobian_inertia(r) if full is None else full
        a, b = r.arm_dof, r.base_dof
        aa, ab = self._blocks[r.prefix]
        jdot_qdot = np.concatenate((dotp @ d.qvel, dotr @ d.qvel))
        t, K = hand_inertia_terms(M[aa], M[ab], J[:, a], J[:, b], jdot_qdot, c.hand_acceleration)
        return t, K, self._base_qacc(r, c.base_acceleration)

    def _base_qacc(self, r: RobotIndex, planar: np.ndarray | None) -> np.ndarray:
        """Return the base joints' accelerations of a planar base acceleration (xddot, yddot, yaw ddot) in the world:
        the planar joints' own; a free joint's (linear in the world, angular in the body's frame)."""
        if planar is None:
            return np.zeros(r.base_dof.size)
        acc = np.asarray(planar, dtype=float)
        if r.base == "planar":
            return acc.copy()
        R = self.scene.data.xmat[r.root_body].reshape(3, 3)
        return np.r_[acc[0], acc[1], 0.0, R.T @ np.array([0.0, 0.0, acc[2]])]

    def step(self, commands: Sequence[RobotCommand]) -> None:
        """Hold one command per robot for one control period (`n_sub` physics steps), then sense."""
        if len(commands) != len(self.scene.robots):
            raise MujocoPlantError(f"{len(commands)} commands for {len(self.scene.robots)} robots")
        wall0 = time.perf_counter()
        self._clean = None
        self._apply_load_changes()
        m, d = self.scene.model, self.scene.data
        t_end = self.t + self.dt
        self._begin_period(commands, t_end)
        for k in range(self.n_sub):
            t = self.t + k * self.config.physics_dt
            loops = self._force_loops()
            for i, (r, c, law) in enumerate(zip(self.scene.robots, commands, self._laws)):
                if r.arm_hold_actuators.size:
                    d.ctrl[r.arm_hold_actuators] = d.qfrc_bias[r.arm_dof]
                if isinstance(law, TorqueArmLaw):
                    bias = self._arm_bias(r, law)
                    tilt = self._tilt(r, c) if law.gains.tilt_stiffness > 0.0 else None
                    hand = self._hand_error(i, r, c, t_end - t) if law.gains.cartesian_stiffness > 0.0 else None
                    d.ctrl[r.arm_actuators] = law.torque(
                        t,
                        d.qpos[r.arm_qpos],
                        d.qvel[r.arm_dof],
                        bias,
                        tilt,
                        hand,
                        loop_wrench=loops.get(i),
                        base_acceleration=d.qacc[r.base_dof],
                        grasped=bool(d.eq_active[r.weld]),
                    )
                if r.base == "planar":
                    d.ctrl[r.base_actuators] = self._planar_base_rates(i, r, c.base_twist)
            mujoco.mj_step(m, d)
            self._clean = [self._sensor_wrench(i) for i in range(len(self._laws))]
            self._joint_samples()
            self._track_slip()
            for i, law in enumerate(self._laws):
                self._hand_sum[i] += self._hand_wrench_world(i, self._clean[i])
                if isinstance(law, AdmittanceArmLaw):  # the F/T at the physics rate: the law takes its period mean
                    law.sample(self._ft_at_grasp(i))
        self.t = t_end
        self._target_prev = [np.asarray(c.hand_target)[:3, 3].copy() for c in commands]
        self._after_period(commands)
        self._stats.wall += time.perf_counter() - wall0
        self._stats.sim += self.dt

    def _begin_period(self, commands: Sequence[RobotCommand], t_end: float) -> None:
        """Check each command and start the period: a torque law takes its wrench and plan, a velocity-servoed arm
        its admittance law's joint velocities, a differential base its wheel rates."""
        d = self.scene.data
        for i, (r, c, law) in enumerate(zip(self.scene.robots, commands, self._laws)):
            self._check_command(r, c)
            if isinstance(law, TorqueArmLaw):
                full = self._site_jacobian_inertia(r)
                J, M = self._arm_jacobian_inertia(r, full)
                inertial = self._hand_inertia(r, c, full) if law.gains.hand_inertia != "off" else None
                law.begin(c.hand_wrench, c.arm_torque, c.arm_position, c.arm_velocity, J, M, t_end, self.dt, inertial)
            else:
                J, _ = self._arm_jacobian_inertia(r)
                w_meas = self._hand_wrench_world(i, self._ft[i])
                q = d.qpos[r.arm_qpos]
                d.ctrl[r.arm_actuators] = law.velocity(
                    c.arm_velocity,
                    c.arm_position,
                    q,
                    d.qvel[r.arm_dof],
                    J,
                    c.hand_wrench,
                    w_meas,
                    self.dt,
                    bias=d.qfrc_bias[r.arm_dof],
                    inertial=self._hand_inertia(r, c) if law.gains.hand_inertia else None,
                )
            if r.base == "differential":
                d.ctrl[r.wheel_actuators] = c.wheel_rates

    def _apply_load_changes(self) -> None:
        """Put in or take out the loads due at this period's start (`mujoco_cart.add_point_mass` on the cart body, at
        the height of its centre of mass); a load put in at rest takes its share of the momentum: M_new v+ = M_old v-
        over the whole scene (no impulse from outside: the wheels' contacts act in the steps after)."""
        m, d, cart = self.scene.model, self.scene.data, self.scene.cart_body
        while self._pending and self._pending[0].t <= self.t + 1e-9:
            change = self._pending.pop(0)
            x, y = self._inertial.com_b if change.xy is None else change.xy
            M_old = np.zeros((m.nv, m.nv))
            mujoco.mj_forward(m, d)
            mujoco.mj_fullM(m, d, M_old)
            mujoco_cart.add_point_mass(m, cart, change.mass, (x, y, float(m.body_ipos[cart][2])))
            mujoco.mj_setConst(m, mujoco.MjData(m))  # body_subtreemass and the other derived constants
            mujoco.mj_forward(m, d)
            if change.mass > 0.0:
                M_new = np.zeros((m.nv, m.nv))
                mujoco.mj_fullM(m, d, M_new)
                d.qvel[:] = np.linalg.solve(M_new, M_old @ d.qvel)
                mujoco.mj_forward(m, d)
            self._inertial = self._read_inertial()
            self.inertial_log.append((round(self.t, 9), self._inertial))

    def _joint_samples(self) -> None:
        """Give each torque law with a fused force loop its arm's external joint torque over the last physics step.

        ``tau_ext = (M qdd)_arm + b_arm - tau_joint``: the joints' accelerations (the engine's; a real arm
        differentiates its encoders) through the model (the whole robot's inertia rows of the arm: the base's
        acceleration included) minus the joints' own torque as output-side joint torque sensors read it (motor,
        passive damping, friction and limit forces): the weld's (and any contact's) torque on the arm, plus the
        sensing's errors (`JointTorqueNoise`: white noise and a per-run offset per joint).
        """
        m, d = self.scene.model, self.scene.data
        laws = self._fused_loops()
        if not laws:
            return
        # d.qM, qfrc_*, efc_* are the step's state (mj_step integrates after them)
        mujoco.mj_mulM(m, d, self._mdv, d.qacc)
        self._joint_frc[:] = 0.0
        internal = self._internal_forces()
        if internal is not None:
            mujoco.mj_mulJacTVec(m, d, self._joint_frc, internal)
        for i, (r, law) in laws:
            a = r.arm_dof
            joint = d.qfrc_actuator[a] + d.qfrc_passive[a] + self._joint_frc[a]
            white, offset = self._joint_noise[i]
            sensed = joint - offset - white * self._rng_joint.standard_normal(white.size)  # normal(0, 1)'s draws
            mount = d.xmat[self._mount_body[i]]  # the link the arm is mounted on
            law.joint_torque_sample(self._mdv[a] + d.qfrc_bias[a] - sensed, mount, sensed)

    def _internal_forces(self) -> np.ndarray | None:
        """Return the constraint forces of the joints' own constraints (dof friction, joint limits), the other rows
        zero (None: no such row). MuJoCo orders the rows equality, friction, limit, contact: without tendons the
        friction and limit rows are the dof frictions and the joint limits."""
        d = self.scene.data
        if self.scene.model.ntendon == 0:
            start, stop = d.ne, d.ne + d.nf + d.nl
            if start == stop:
                return None
            forces = np.zeros(d.nefc)
            forces[start:stop] = d.efc_force[start:stop]
            return forces
        efc_type = d.efc_type
        internal = (efc_type == _JOINT_INTERNAL[0]) | (efc_type == _JOINT_INTERNAL[1])
        return np.where(internal, d.efc_force, 0.0) if internal.any() else None

    def _planar_base_rates(self, i: int, r: RobotIndex, twist: np.ndarray) -> np.ndarray:
        """Return the planar base's servo setpoints (world rates): the commanded body twist + the PI loop's integral."""
        d, sv = self.scene.data, self.config.servos
        yaw = float(d.qpos[r.base_qpos[2]])
        cy, sy = math.cos(yaw), math.sin(yaw)
        vx, vy, wz = twist.tolist() if isinstance(twist, np.ndarray) else twist
        rates = np.array([cy * vx - sy * vy, sy * vx + cy * vy, wz])
        if sv.base_integral > 0.0:
            lim = sv.base_integral_limit
            e = self._base_int[i] + self.config.physics_dt * (rates - d.qvel[r.base_dof])
            self._base_int[i] = np.minimum(np.maximum(e, -lim), lim)  # np.clip's arithmetic
            rates = rates + sv.base_integral * self._base_int[i]
        return rates

    def _arm_bias(self, r: RobotIndex, law: TorqueArmLaw) -> np.ndarray:
        """Return the arm's feed-forward besides J^T w: bias forces, or inverse dynamics (see `TorqueArmGains`)."""
        m, d = self.scene.model, self.scene.data
        if law.gains.feedforward not in ("dynamics", "base"):
            return d.qfrc_bias[r.arm_dof]
        acc = self._qacc
        acc[:] = d.qacc  # the last step's accelerations: the base's is measured
        acc[r.arm_dof] = law.a_plan if law.gains.feedforward == "dynamics" else 0.0
        saved = d.qacc.copy()
        d.qacc[:] = acc
        mujoco.mj_rne(m, d, 1, self._rne)
        d.qacc[:] = saved
        return self._rne[r.arm_dof]

    def _hand_error(self, i: int, r: RobotIndex, c: RobotCommand, to_end: float) -> tuple[np.ndarray, np.ndarray]:
        """Return (hand target position - hand position, target velocity - hand velocity), world frame."""
        d = self.scene.data
        target = np.asarray(c.hand_target)[:3, 3]
        prev = self._target_prev[i]
        v_target = (target - prev) / self.dt if prev is not None else np.zeros(3)
        mujoco.mj_objectVelocity(self.scene.model, d, mujoco.mjtObj.mjOBJ_SITE, r.hand_site, self._vel6, 0)
        # the target is where the hand should be at the period's end: interpolate back along its velocity
        return target - v_target * to_end - d.site_xpos[r.hand_site], v_target - self._vel6[3:]

    def _tilt(self, r: RobotIndex, c: RobotCommand) -> tuple[np.ndarray, np.ndarray]:
        """Return (rotation error from the hand to its target, the hand's angular velocity), world frame."""
        d = self.scene.data
        R = d.site_xmat[r.hand_site].reshape(3, 3)
        err = np.zeros(3)
        mujoco.mju_mat2Quat(self._quat, np.ascontiguousarray(np.asarray(c.hand_target)[:3, :3] @ R.T).reshape(9))
        mujoco.mju_quat2Vel(err, self._quat, 1.0)
        b = self.scene.cart_body  # the hand turns with the handle it holds
        omega = d.xmat[b].reshape(3, 3) @ d.qvel[self.scene.cart_dof + 3 : self.scene.cart_dof + 6]
        return err, omega

    def _check_command(self, r: RobotIndex, c: RobotCommand) -> None:
        n = r.arm_qpos.size
        if np.shape(c.arm_torque) != (n,) or np.shape(c.arm_position) != (n,) or np.shape(c.arm_velocity) != (n,):
            raise MujocoPlantError(f"arm commands must have shape ({n},)")
        if np.shape(c.hand_wrench) != (6,):
            raise MujocoPlantError("hand_wrench must have shape (6,)")
        if r.base == "differential" and np.shape(c.wheel_rates) != (r.wheel_actuators.size,):
            raise MujocoPlantError(f"wheel_rates must have shape ({r.wheel_actuators.size},)")

    def _track_slip(self) -> None:
        d, st = self.scene.data, self._stats
        for r in self.scene.robots:
            gap = d.site_xpos[r.hand_site] - d.site_xpos[r.handle_site]
            slip = math.sqrt(float(gap @ gap))
            if slip > st.slip_max:
                st.slip_max = slip

    def _split_error(self, commands: Sequence[RobotCommand]) -> None:
        """Add the period's hand wrench errors (period mean minus allocated, stacked) to the diagnostics as their part
        in the cart's net wrench and in the squeeze (`net_wrench_projector` at the grasps; force rows, as
        ``wrench_error_rms_n``; with one hand all of it is net)."""
        robots = range(len(self.scene.robots))
        e = np.concatenate([self._hand_clean[i] - np.asarray(commands[i].hand_wrench, dtype=float) for i in robots])
        net = self._net_projector(robots) @ e if len(robots) > 1 else e  # one hand's projector is the identity
        forces = self._force_rows
        self._stats.err_net_sq += float(net[forces] @ net[forces])
        internal = (e - net)[forces]
        self._stats.err_internal_sq += float(internal @ internal)

    def _after_period(self, commands: Sequence[RobotCommand]) -> None:
        """Unwrap the headings, sense, and add the period to the diagnostics."""
        d, st = self.scene.data, self._stats
        th = mujoco_cart.yaw_of(d.xquat[self.scene.cart_body])
        self._theta += math.remainder(th - self._theta_prev, 2.0 * math.pi)
        self._theta_prev = th
        for i, r in enumerate(self.scene.robots):
            if r.base == "differential":
                yaw = mujoco_cart.yaw_of(d.xquat[r.root_body])
                self._base_yaw[i] += math.remainder(yaw - self._yaw_prev[i], 2.0 * math.pi)
                self._yaw_prev[i] = yaw
                st.wheel_slip_max = max(st.wheel_slip_max, self._wheel_slip(r))
            # the hand's wrench over the period (noise-free F/T, mean of the physics steps): what the cart integrates
            self._hand_clean[i] = self._hand_sum[i] / self.n_sub
            self._hand_sum[i] = np.zeros(6)
            err = self._hand_clean[i][:3] - np.asarray(commands[i].hand_wrench[:3])
            st.err_sq += float(err @ err)
            st.force_sq += float(np.dot(commands[i].hand_wrench[:3], commands[i].hand_wrench[:3]))
            st.per_robot_err[i][0] += float(err @ err)
            st.per_robot_err[i][1] += 1
            self._ft[i] = self._ft_reading(i, noisy=True)
            law = self._laws[i]
            if isinstance(law, TorqueArmLaw):
                st.arm_force_peak_ratio = max(st.arm_force_peak_ratio, law.peak_ratio)
                st.arm_saturated = max(st.arm_saturated, law.saturated_steps)
                st.arm_task_peak_ratio = max(st.arm_task_peak_ratio, law.peak_task_ratio)
                st.arm_scaled = max(st.arm_scaled, law.scaled_steps)
                st.joint_peak_ratio[i] = law.peak_joint_ratio
            else:  # the joint's torque: its servo's and its drive's hold of the static load (the joint clamps the sum)
                joint = d.actuator_force[r.arm_actuators] + d.actuator_force[r.arm_hold_actuators]
                ratio = np.max(np.abs(joint) / r.effort_limit)
                st.arm_force_peak_ratio = max(st.arm_force_peak_ratio, float(ratio))
        self._split_error(commands)
        self._cart_tilt()
        st.n += 1
        self._z = self._motion_capture()
        for record in [self.cart_joints, *self.robot_joints]:
            record.record(self.t, d)

    def _cart_tilt_deg(self) -> float:
        """Return the cart body's tilt from upright (deg): the angle of its z axis from the world's."""
        return math.degrees(math.acos(min(1.0, float(self.scene.data.xmat[self.scene.cart_body][8]))))

    def _cart_tilt(self) -> None:
        """Record the cart body's tilt from upright, and when it first passed `STANDING_TILT_DEG` (it tips over:
        the planar cart model no longer holds)."""
        st = self._stats
        tilt = self._cart_tilt_deg()
        st.cart_tilt_max_deg = max(st.cart_tilt_max_deg, tilt)
        if st.cart_tipped_at_s is None and tilt > STANDING_TILT_DEG:
            st.cart_tipped_at_s = float(self.t)

    def _wheel_slip(self, r: RobotIndex) -> float:
        """Return the largest horizontal slip speed (m/s) of the robot's driven wheels' contact points."""
        m, d = self.scene.model, self.scene.data
        worst = 0.0
        vel = np.zeros(6)
        for b in r.wheel_bodies:
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, int(b), vel, 0)
            w, v = vel[:3], vel[3:]
            contact = v + np.cross(w, np.array([0.0, 0.0, -r.wheel_radius]))
            worst = max(worst, float(math.hypot(contact[0], contact[1])))
        return worst

    # ------------------------------------------------------------------ report

    def report(self) -> dict:
        """Return the run's diagnostics (JSON-ready; ``base_wheel_slip_max_m_s`` is None without a differential base)."""
        st, ci = self._stats, self._inertial
        n = max(st.n * len(self.scene.robots), 1)
        differential = any(r.base == "differential" for r in self.scene.robots)
        return {
            "cart_mass_kg": ci.mass,
            "cart_mass_effective_kg": ci.mass_effective,
            "cart_com_b_m": [float(v) for v in ci.com_b],
            "cart_inertia_kg_m2": ci.inertia,
            "wrench_error_rms_n": math.sqrt(st.err_sq / n),
            "wrench_error_net_rms_n": math.sqrt(st.err_net_sq / n),
            "wrench_error_internal_rms_n": math.sqrt(st.err_internal_sq / n),
            "hand_force_rms_n": math.sqrt(st.force_sq / n),
            "grasp_slip_max_m": st.slip_max,
            "cart_tilt_max_deg": st.cart_tilt_max_deg,
            "cart_tipped_at_s": st.cart_tipped_at_s,
            "cart_tilt_limit_deg": STANDING_TILT_DEG,
            "base_wheel_slip_max_m_s": st.wheel_slip_max if differential else None,
            "plant_arm_torque_limit_ratio": st.arm_force_peak_ratio,
            "arm_torque_saturated_steps": int(st.arm_saturated),
            "plant_arm_task_torque_limit_ratio": st.arm_task_peak_ratio,
            "plant_arm_torque_scaled_steps": int(st.arm_scaled),
            "plant_arm_joint_torque_limit_ratio": {
                str(i): [round(float(x), 4) for x in r] for i, r in sorted(st.joint_peak_ratio.items())
            },
            "real_time_factor": st.sim / st.wall if st.wall > 0 else None,
            "physics_dt_s": self.config.physics_dt,
            "control_dt_s": self.config.control_dt,
            "cart_source": self.cart_source.label,
            "cart_joints": self.cart_joints,
            "robot_joints": self.robot_joints,
        }
