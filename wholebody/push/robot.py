"""One mobile manipulator holding the handle: grasp geometry, whole-body QP tracker, arm torques, F/T sensing."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from collections.abc import Sequence
from functools import lru_cache
from typing import TypeVar

import numpy as np
import pinocchio as pin

import robots
from robots.checks import wheel_geometry
from robots.profiles import RobotProfile
from cart.simulate import MeasurementNoise
from wholebody.contacts.handle import contact_grid
from wholebody.push.file_version import file_version
from wholebody.push.geometry import DEFAULT_GEOMETRY, CartGeometry
from wholebody.errors import WholeBodyError
from wholebody.motion.control import ControllerConfig, ResolvedRateController, StepResult
from wholebody.motion.bases import DifferentialDrive
from wholebody.motion.kinematics import WholeBody, wholebody_for
from wholebody.motion.limits import JointTorqueLimit, WheelAccelerationLimit
from wholebody.motion.qp import Limit
from wholebody.motion.tasks import FrameTask
from wholebody.push.config import BodyTracker
from wholebody.contacts.allocation import TorqueConstraint

T = TypeVar("T")

#: Grasp orientation in {b} at pitch 0: tool axis (ee z) along +x_b, fingers (ee x) along z_b, bar along ee y.
R_B_EE0 = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
#: Default grasp pitch (rad, about y_b): the tool points forward and 46 deg down onto the bar.
GRASP_PITCH = 0.8
#: Base origin relative to its contact point, in {b} (x behind the handle), and base yaw relative to the cart.
BASE_OFFSET_X = -0.65
#: Lateral offset (m) of each base beyond its contact when two robots push side by side and the URDF gives no box
#: fixed to the base (`side_by_side_spread`).
TWO_ARM_BASE_SPREAD = 0.25
#: Clearance (m) between the footprints of two robots pushing side by side (`side_by_side_spread`).
BASE_CLEARANCE = 0.1
#: Look-ahead (m) of a differential base's tracker when its profile gives none (paper 2 section VI).
DIFFERENTIAL_LOOKAHEAD = 0.3
#: Rim acceleration (m/s^2) a profile without tuned push settings gets as its wheel acceleration limit.
DEFAULT_RIM_ACCELERATION = 2.5
#: Contact point y (m) of a fixed contact when the profile gives none.
DEFAULT_CONTACT_Y = 0.0
#: Share of each arm joint's URDF effort the whole-body QP's torque limit allows (`JointTorqueLimit`): the rest
#: covers the velocity terms' change over one period, which the QP's linear torque model takes at the last input.
TORQUE_LIMIT_FRACTION = 0.98


def _axis_rotation(axis: str) -> np.ndarray:
    """Return R with R @ e_axis = e_z: gripper-frame coordinates -> the canonical grasp frame (tool axis z)."""
    c = {"z": (0.0, 0.0), "-z": (1.0, 0.0), "x": (0.0, 1.0), "-x": (0.0, -1.0), "y": (2.0, 1.0), "-y": (2.0, -1.0)}
    kind, s = c[axis]
    if kind == 0.0 and s == 0.0:
        return np.eye(3)
    if kind == 1.0:  # -z: half turn about x
        return np.diag([1.0, -1.0, -1.0])
    if kind == 0.0:  # +-x: quarter turn about y by +-90 deg
        return np.array([[0.0, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, 0.0]])
    return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -s], [0.0, s, 0.0]])  # +-y: quarter turn about x by +-90 deg


def grasp_rotation(pitch: float = GRASP_PITCH, roll: float = 0.0, tool_axis: str = "z") -> np.ndarray:
    """Return R_b_ee of the grasp: R_y(pitch) @ R_B_EE0 @ R_z(roll) @ A(tool_axis).

    At roll 0 with the tool along the gripper frame's z the bar lies along the ee y axis; ``tool_axis``
    names the gripper frame's axis that points from the wrist to the fingertips (A maps it onto z).
    """
    c, s = math.cos(pitch), math.sin(pitch)
    R = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ R_B_EE0
    if roll != 0.0:
        cr, sr = math.cos(roll), math.sin(roll)
        R = R @ np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    if tool_axis != "z":
        R = R @ _axis_rotation(tool_axis)
    return R


def cart_se3(q_cart: Sequence[float] | np.ndarray, geometry: CartGeometry | None = None) -> pin.SE3:
    """Return T_s_b: the cart frame {b} in the world, at the geometry's height (default: wheel-axle height)."""
    c, s = math.cos(q_cart[2]), math.sin(q_cart[2])
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return pin.SE3(R, np.array([q_cart[0], q_cart[1], (geometry or DEFAULT_GEOMETRY).frame_height]))


def handle_point(y: float, geometry: CartGeometry | None = None) -> np.ndarray:
    """Return the handle point with lateral coordinate y, in {b} (default: the shopping cart's handle)."""
    return (geometry or DEFAULT_GEOMETRY).point(y)


def grasp_target(
    q_cart: np.ndarray,
    qd_cart: np.ndarray,
    y: float,
    ydot: float,
    R_b_ee: np.ndarray,
    geometry: CartGeometry | None = None,
) -> tuple[pin.SE3, np.ndarray]:
    """Return (world pose of the grasp frame, its spatial velocity (v, w) world-aligned at the grasp point)."""
    T_sb = cart_se3(q_cart, geometry)
    p_b = handle_point(y, geometry)
    T = T_sb * pin.SE3(R_b_ee, p_b)
    r = T_sb.rotation @ p_b
    om = qd_cart[2]
    v = np.array([qd_cart[0] - om * r[1], qd_cart[1] + om * r[0], 0.0]) + T_sb.rotation @ np.array([0.0, ydot, 0.0])
    return T, np.concatenate([v, [0.0, 0.0, om]])


def base_target(q_cart: np.ndarray, qd_cart: np.ndarray, offset_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (planar pose, world rates) of a base rigidly offset by offset_b = (x, y) in {b}, same heading."""
    c, s = math.cos(q_cart[2]), math.sin(q_cart[2])
    px, py = c * offset_b[0] - s * offset_b[1], s * offset_b[0] + c * offset_b[1]
    om = qd_cart[2]
    pose = np.array([q_cart[0] + px, q_cart[1] + py, q_cart[2]])
    return pose, np.array([qd_cart[0] - om * py, qd_cart[1] + om * px, om])


#: Whole-body QP settings of the push (task weight 1; the posture and base pulls are 1e-4 and 1e-3 of it).
PUSH_CONTROLLER = ControllerConfig(
    gain=20.0,
    damping=1e-7,
    secondary="posture",
    secondary_weight=1e-4,
    posture_gain=1.0,
    max_linear_speed=3.0,
    max_angular_speed=3.0,
    limit_margin=0.05,
    solver="daqp",
    fallback_solver="proxqp",
    base_weight=1e-3,
    base_gain=2.0,
)


class WholeBodyQPTracker:
    """`BodyTracker` of the project's whole-body QP (`wholebody.motion.control.ResolvedRateController`).

    The grasp frame follows the handle (feed-forward + `gain` feedback), the arm is pulled to its
    grasp posture, and the base to its nominal place behind its contact point (the controller's
    base regularisation). Bounds: joint positions/rates, the wheel speeds of the URDF (which imply
    the base's twist limits), and the profile's wheel acceleration limit: on the wheel rates of a
    differential drive, on the body twist (wheel radius x limit per second) of a holonomic base.
    """

    def __init__(
        self,
        wb: WholeBody,
        q_nominal: np.ndarray,
        config: ControllerConfig | None = None,
        hand_frames: Sequence[int] = (),
    ) -> None:
        extra: list[Limit] = []
        if config is None:  # the robot's own base tracker and wheel limits (its profile)
            prof = filled_profile(wb.robot)
            config = replace(
                PUSH_CONTROLLER,
                base_lookahead=_filled(prof, "base_lookahead", prof.base_lookahead),
                wheel_acceleration_limit=prof.wheel_acceleration_limit,
            )
            if wb.base_input == "twist" and prof.wheel_acceleration_limit is not None:
                extra.append(WheelAccelerationLimit(wb, prof.wheel_acceleration_limit * wb.base.wheel_radius))
        #: the arm joints' torques the step asks for stay within their URDF efforts (`set_hand_wrenches`)
        self.torque_limit = JointTorqueLimit(wb, TORQUE_LIMIT_FRACTION, config.limit_margin)
        extra.append(self.torque_limit)
        c = config
        #: one task per further hand (`hand_frames`: their frame ids), with the first hand's weight and gain
        self.hands = [
            FrameTask(wb, f, c.position_weight, c.gain, c.max_linear_speed, c.max_angular_speed) for f in hand_frames
        ]
        self.controller = ResolvedRateController(
            wb, config, posture=q_nominal, extra_limits=extra, extra_tasks=self.hands
        )
        self.last: StepResult | None = None

    def step(
        self,
        x: np.ndarray,
        target: pin.SE3,
        target_velocity: np.ndarray,
        base_target: np.ndarray,
        base_velocity: np.ndarray,
        dt: float,
        more_targets: Sequence[tuple[pin.SE3, np.ndarray]] = (),
    ) -> np.ndarray:
        """Return u = [arm rates (n_arm), base input] for one period; `more_targets`: (pose, twist) of each
        further hand (`hand_frames`), tracked in the same QP."""
        if len(more_targets) != len(self.hands):
            raise WholeBodyError(f"{len(more_targets)} further hand targets for {len(self.hands)} further hands")
        for task, (T, v) in zip(self.hands, more_targets):
            task.target, task.target_velocity = T, np.asarray(v, dtype=float)
        res = self.controller.step(
            x, target, target_velocity, dt, base_target=base_target, base_target_velocity=base_velocity
        )
        if not res.solver_ok:
            raise WholeBodyError("the whole-body velocity QP has no solution")
        self.last = res
        return res.u


def solve_grasp_ik(
    wb: WholeBody, base_pose: np.ndarray, target: pin.SE3, seed: Sequence[float] | np.ndarray
) -> np.ndarray:
    """Return arm joints placing the ee at target with the base at base_pose (bounded least squares)."""
    from scipy.optimize import least_squares

    x = np.r_[base_pose, np.zeros(wb.n_arm)]

    def residual(qa: np.ndarray) -> np.ndarray:
        x[3:] = qa
        return pin.log6(wb.ee_placement(x).actInv(target)).vector

    lo, hi = wb.arm_lower + 0.02, wb.arm_upper - 0.02
    sol = least_squares(residual, np.clip(seed, lo, hi), bounds=(lo, hi), xtol=1e-12, ftol=1e-12)
    if np.linalg.norm(sol.fun) > 1e-5:
        x[3:] = sol.x
        gap = float(np.linalg.norm(wb.ee_placement(x).translation - target.translation))
        h = target.translation
        raise WholeBodyError(
            f"the arm cannot reach the handle from base pose {np.round(base_pose, 3)}: the handle point is at "
            f"({h[0]:.2f}, {h[1]:.2f}, {h[2]:.2f}) m and the closest grasp leaves the hand {1e3 * gap:.0f} mm from it "
            f"(pose residual {np.linalg.norm(sol.fun):.3g}); a handle this high or low, or this far, is out of the "
            "arm's reach from where the base stands"
        )
    return sol.x


def grasp_configuration(
    wb: WholeBody,
    prof: RobotProfile,
    q_cart: np.ndarray,
    contact_y: float,
    base_y: float,
    R_b_ee: np.ndarray,
    seed: Sequence[float] | np.ndarray | None = None,
    geometry: CartGeometry | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (base pose, arm joints) of the robot holding the handle at `contact_y` (m, in {b}).

    The base stands at ``(handle x + prof.push_base_x, base_y)`` in the cart frame {b}; the hand holds the bar
    with orientation ``R_b_ee``; the arm comes from `solve_grasp_ik` seeded with `seed` (default: the
    profile's push posture). `prof` is a profile with its push settings filled (`push_profile`).
    """
    offset = np.array([handle_point(contact_y, geometry)[0] + prof.push_base_x, base_y])
    pose, _ = base_target(q_cart, np.zeros(3), offset)
    target, _ = grasp_target(q_cart, np.zeros(3), contact_y, 0.0, R_b_ee, geometry)
    arm_seed = seed if seed is not None else _arm_of(prof, wb).push_seed
    qa = solve_grasp_ik(wb, pose, target, arm_seed)
    return pose, qa


# ---------------------------------------------------------------------------------------------- push settings
def _arm_of(prof: RobotProfile, wb: WholeBody):
    """Return the profile's arm that `wb` drives (matched by its joints)."""
    for arm in prof.arms:
        if arm.joints == wb.arm_joints:
            return arm
    raise WholeBodyError(f"the whole-body model's joints are not an arm of robot {prof.name!r}'s profile")


def tool_axis(wb: WholeBody) -> str:
    """Return the gripper frame's axis pointing from the wrist to the fingertips, read off the URDF.

    The last arm joint's origin, seen from the gripper frame at the reference configuration, lies behind
    the tool: the tool axis is minus its largest component. A gripper frame at that origin (Unitree Z1's
    ``link06``) is read against the joint before it, and so on ("z" when every arm joint's origin coincides).
    """
    q = wb.to_pinocchio_q(np.r_[0.0, 0.0, 0.0, np.clip(np.zeros(wb.n_arm), wb.arm_lower, wb.arm_upper)])
    pin.forwardKinematics(wb.model, wb.data, q)
    pin.updateFramePlacements(wb.model, wb.data)
    for name in reversed(wb.arm_joints):
        p = wb.data.oMf[wb.ee_frame_id].actInv(wb.data.oMi[wb.model.getJointId(name)].translation)
        k = int(np.argmax(np.abs(p)))
        if abs(p[k]) >= 1e-6:
            return ("-" if p[k] > 0 else "") + "xyz"[k]
    return "z"


def base_twist_limit(wb: WholeBody) -> tuple[float, float, float]:
    """Return the largest base body twist (vx, vy, wz) per axis that keeps every wheel within its URDF speed limit."""
    if isinstance(wb.base, DifferentialDrive):  # rim speed r w and turn rate 2 r w / track
        v = wb.base.wheel_radius * float(np.min(wb.wheel_velocity_limit))
        return (v, 0.0, 2.0 * v / wb.base.track)
    M = wb.base.body_twist_to_wheels
    out = []
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        rates = np.abs(M(e))
        if not wb.base.holonomic and k == 1:
            out.append(0.0)
            continue
        out.append(float(np.min(wb.wheel_velocity_limit[rates > 1e-12] / rates[rates > 1e-12])))
    return (out[0], out[1], out[2])


def _filled(prof: RobotProfile, key: str, value: T | None) -> T:
    """Return a push setting of a profile filled by `push_profile`; raise `WholeBodyError` if it is not set."""
    if value is None:
        raise WholeBodyError(f"robot {prof.name!r}: push setting {key} is not set; take the profile from push_profile")
    return value


def push_profile(robot: robots.LoadedRobot | RobotProfile | str, arm: int = 0) -> RobotProfile:
    """Return the robot's profile with every push setting filled: the profile's own values, the rest computed.

    Computed: the tool axis (`tool_axis`), base twist limits from the wheel speeds (`base_twist_limit`),
    the base tracker's look-ahead (0.3 m differential, 0 holonomic), the fixed contact (0 m) and, when the
    profile holds no tuned push posture, the grasp (pitch, roll), the base placement behind the handle and
    each arm's push posture by IK (`solve_push_placement`). Cached per profile and URDF.
    """
    loaded = robot if isinstance(robot, robots.LoadedRobot) else robots.load(robot)
    if loaded.profile is None:
        raise WholeBodyError(f"robot {loaded.name!r} was built without a profile; load it with robots.load(...)")
    return _push_profile(loaded.profile, str(loaded.urdf), _LoadedKey(loaded))


class _LoadedKey:
    """Carries a loaded robot into the cache; of it only its URDF file's version is part of the key (an edited
    URDF is read again)."""

    def __init__(self, robot: robots.LoadedRobot) -> None:
        self.robot = robot
        self.version = file_version(robot.urdf)

    def __hash__(self) -> int:
        return hash(self.version)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _LoadedKey) and other.version == self.version


@lru_cache(maxsize=32)
def _push_profile(prof: RobotProfile, urdf: str, key: _LoadedKey) -> RobotProfile:
    out = _filled_profile(prof, urdf, key)
    if out.tuned:
        return replace(
            out,
            grasp_pitch=GRASP_PITCH if out.grasp_pitch is None else out.grasp_pitch,
            grasp_roll=out.grasp_roll or 0.0,
        )
    from wholebody.push.posture import solve_push_placement

    wbs = [wholebody_for(key.robot, base_input=prof.base_input, arm=i) for i in range(len(prof.arms))]
    return solve_push_placement(out, wbs)


def filled_profile(robot: robots.LoadedRobot) -> RobotProfile:
    """Return the robot's profile with the push settings that need no IK filled (`push_profile` without the
    placement search): tool axes, base twist limits, the base tracker's look-ahead, the fixed contact and the
    wheel acceleration limit. Cached per profile and URDF."""
    if robot.profile is None:
        raise WholeBodyError(f"robot {robot.name!r} was built without a profile; load it with robots.load(...)")
    return _filled_profile(robot.profile, str(robot.urdf), _LoadedKey(robot))


@lru_cache(maxsize=32)
def _filled_profile(prof: RobotProfile, urdf: str, key: _LoadedKey) -> RobotProfile:
    if not prof.is_mobile_manipulator:
        raise WholeBodyError(f"robot {prof.name!r} cannot push the cart: its profile has no arm on a wheeled base")
    robot = key.robot
    wbs = [wholebody_for(robot, base_input=prof.base_input, arm=i) for i in range(len(prof.arms))]
    arms = tuple(replace(a, tool_axis=a.tool_axis or tool_axis(wb)) for a, wb in zip(prof.arms, wbs))
    out = replace(
        prof,
        arms=arms,
        push_contact_y=DEFAULT_CONTACT_Y if prof.push_contact_y is None else prof.push_contact_y,
        base_twist_limit=prof.base_twist_limit or base_twist_limit(wbs[0]),
        base_lookahead=(DIFFERENTIAL_LOOKAHEAD if prof.base == "differential" else 0.0)
        if prof.base_lookahead is None
        else prof.base_lookahead,
    )
    if not out.tuned and out.wheel_acceleration_limit is None:  # rim acceleration 2.5 m/s^2 (Ridgeback's)
        out = replace(out, wheel_acceleration_limit=DEFAULT_RIM_ACCELERATION / wheel_geometry(out, robot.model).radius)
    return out


class MobileManipulator:
    """One mobile manipulator holding the handle with one of its arms, or with several (one base driving them).

    State ``x`` = [base pose, arm joints (each arm's in turn)]; ``base_offset_b`` is where its base stays, in
    {b} (behind the handle, laterally at ``base_y``); the arms start from the grasp IK. ``arm`` picks the
    profile's arm, or a sequence of arms whose hands hold ``contact_y`` (one each, in that order) with grasp
    rotations ``R_b_ee`` (one, or one per hand); the push settings come from `push_profile` (``base_x``:
    the base's x relative to the handle instead of the profile's).
    """

    def __init__(
        self,
        robot: robots.LoadedRobot,
        q_cart: np.ndarray,
        contact_y: float | Sequence[float] | np.ndarray,
        base_y: float,
        R_b_ee: np.ndarray | Sequence[np.ndarray],
        tracker: BodyTracker | None = None,
        arm_seed: Sequence[float] | np.ndarray | Sequence[Sequence[float] | None] | None = None,
        arm: int | Sequence[int] = 0,
        geometry: CartGeometry | None = None,
        base_x: float | None = None,
    ) -> None:
        several = not isinstance(arm, int) and len(arm) > 1  # their grasps and place: `multi_arm_placement`
        prof = filled_profile(robot) if several and base_x is not None else push_profile(robot)
        if base_x is not None:  # a place of its own
            prof = replace(prof, push_base_x=base_x)
        self.geometry = geometry or DEFAULT_GEOMETRY
        self.profile = prof
        #: the profile's arms this robot drives, one per hand, in the order of the hands (and of x, u)
        self.arms = (arm,) if isinstance(arm, int) else tuple(int(i) for i in arm)
        self.arm = prof.arms[self.arms[0]]
        ys = np.atleast_1d(np.asarray(contact_y, dtype=float))
        Rs = [np.asarray(R_b_ee)] if np.ndim(R_b_ee) == 2 else [np.asarray(R) for R in R_b_ee]
        if not len(ys) == len(Rs) == len(self.arms):
            raise WholeBodyError(f"{len(ys)} contacts and {len(Rs)} grasps for {len(self.arms)} arm(s)")
        # a holonomic base takes a body twist; a differential drive takes wheel rates, so that its lateral
        # velocity is zero by construction (combined Jacobian of paper 2, eq. 11-21)
        self.wb = wholebody_for(robot, base_input=prof.base_input, arm=arm)
        self.model = self.wb.model
        self.data = self.model.createData()
        self.R_b_ee, self.grasp_rotations = Rs[0], Rs
        self.ee_id = self.wb.ee_frame_id
        self.hand_ids = [robot.frame_id(prof.arms[i].gripper_frame) for i in self.arms]
        self.ft_ids = [robot.frame_id(prof.arms[i].sensor_frame) for i in self.arms]
        self.ft_id = self.ft_ids[0]
        edges = np.cumsum([0] + [len(prof.arms[i].joints) for i in self.arms])
        #: each hand's arm joints: a slice of the arm part of x (and of u)
        self.hand_cols = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
        self.base_offset_b = np.array([handle_point(float(ys.mean()), self.geometry)[0] + prof.push_base_x, base_y])
        pose, qa = self._grasp(robot, q_cart, ys, base_y, arm_seed)
        self.x = np.r_[pose, qa]
        self.tracker = (
            tracker if tracker is not None else WholeBodyQPTracker(self.wb, qa, hand_frames=self.hand_ids[1:])
        )
        self.u = np.zeros(self.wb.n_u)
        #: the arm joints' torque limits from the URDF (N m; N for a prismatic joint), every arm's in turn
        self.effort_limit = self.wb.arm_effort_limit

    def _grasp(self, robot, q_cart, ys, base_y, seeds) -> tuple[np.ndarray, np.ndarray]:
        """Return (base pose, arm joints of every hand) holding the handle at `ys` from the base at `base_y`."""
        if len(self.arms) == 1:
            return grasp_configuration(
                self.wb, self.profile, q_cart, float(ys[0]), base_y, self.R_b_ee, seeds, geometry=self.geometry
            )
        pose, _ = base_target(q_cart, np.zeros(3), self.base_offset_b)
        seeds = list(seeds) if seeds is not None else [None] * len(self.arms)
        parts = []
        for i, y, R, seed in zip(self.arms, ys, self.grasp_rotations, seeds):
            wb = wholebody_for(robot, base_input=self.profile.base_input, arm=i)
            target, _ = grasp_target(q_cart, np.zeros(3), float(y), 0.0, R, self.geometry)
            seed = seed if seed is not None else self.profile.arms[i].push_seed
            parts.append(
                solve_grasp_ik(wb, pose, target, 0.5 * (wb.arm_lower + wb.arm_upper) if seed is None else seed)
            )
        return pose, np.concatenate(parts)

    def set_hand_wrenches(self, wrenches_world: Sequence[np.ndarray]) -> None:
        """Tell the whole-body QP's torque limit the wrench each hand applies in the coming period (world-aligned)."""
        limit = getattr(self.tracker, "torque_limit", None)
        if isinstance(limit, JointTorqueLimit):
            limit.wrenches = list(zip(self.hand_ids, (np.asarray(w, dtype=float) for w in wrenches_world)))

    @property
    def n_hands(self) -> int:
        """Return how many hands this robot holds the handle with."""
        return len(self.arms)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Return the arm joints' names (base to tip, every arm's in turn)."""
        return self.wb.arm_joints

    def body_twist(self, u: np.ndarray) -> np.ndarray:
        """Return the base body twist (vx, vy, wz) of an input u (vy = 0 exactly for a differential drive)."""
        return self.wb.body_twist(u)

    def pin_state(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return Pinocchio (q, v) for the current x and input u (wheel joints left at rest)."""
        q = self.wb.to_pinocchio_q(self.x)
        v = np.zeros(self.model.nv)
        v[0:3] = self.body_twist(u)  # planar root joint: body twist
        v[self.wb.arm_idx_v] = u[: self.wb.n_arm]
        return q, v

    def hand_torques(
        self, u: np.ndarray, u_prev: np.ndarray, dt: float, wrenches_world: Sequence[np.ndarray]
    ) -> tuple[list[np.ndarray], list[np.ndarray], list[pin.SE3]]:
        """Return per hand (arm torques, push part J^T w, hand placement).

        tau = rnea(q, v, a)[arms] + sum_h J_h^T w_h with w_h = [f; n] world-aligned at hand h (the wrench it
        applies to the cart; the cart pushes back with -w), split into each hand's arm joints.
        """
        q, v = self.pin_state(u)
        _, v_prev = self.pin_state(u_prev)
        tau = pin.rnea(self.model, self.data, q, v, (v - v_prev) / dt)[self.wb.arm_idx_v]
        push = np.zeros(self.wb.n_arm)
        for fid, w in zip(self.hand_ids, wrenches_world):
            J = pin.computeFrameJacobian(self.model, self.data, q, fid, pin.LOCAL_WORLD_ALIGNED)
            push += J[:, self.wb.arm_idx_v].T @ w
        pin.updateFramePlacements(self.model, self.data)
        total = tau + push
        hands = [pin.SE3(self.data.oMf[f]) for f in self.hand_ids]
        return [total[c] for c in self.hand_cols], [push[c] for c in self.hand_cols], hands

    def torques(
        self, u: np.ndarray, u_prev: np.ndarray, dt: float, wrench_world: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, pin.SE3, pin.SE3]:
        """Return (arm torques, push part J^T w, ee placement, F/T sensor placement) of the first hand's wrench
        (`hand_torques` for every hand)."""
        taus, pushes, hands = self.hand_torques(u, u_prev, dt, [wrench_world])
        return taus[0], pushes[0], hands[0], pin.SE3(self.data.oMf[self.ft_id])

    def torque_constraints(
        self, q_cart: Sequence[float] | np.ndarray, u: np.ndarray | None = None
    ) -> list[TorqueConstraint]:
        """Return each hand's joint-torque constraint on its wrench in {a}: |J_a^T w_a + bias| <= tau_max.

        ``J_a`` (6 x the hand's arm joints) is the hand Jacobian (world-aligned, its arm's columns) with its rows
        rotated into the cart frame of pose `q_cart` (a wrench in {a} is oriented like {b}); ``bias`` =
        rnea(q, v, 0): gravity and the velocity terms of input `u` (default: the last command); the accelerations
        the whole-body QP will command are not known yet (the allocation's margin covers them). Arms share no
        joint (`robots.checks`), so each hand's constraint is its own. `WrenchAllocator.set_torque_limits` takes them.
        """
        q, v = self.pin_state(self.u if u is None else u)
        bias = pin.rnea(self.model, self.data, q, v, np.zeros(self.model.nv))[self.wb.arm_idx_v]
        c, s = math.cos(q_cart[2]), math.sin(q_cart[2])
        Rt = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # R_sb^T
        out = []
        for fid, cols in zip(self.hand_ids, self.hand_cols):
            J = pin.computeFrameJacobian(self.model, self.data, q, fid, pin.LOCAL_WORLD_ALIGNED)
            Ja = J[:, self.wb.arm_idx_v[cols]]
            names = self.joint_names[cols]
            out.append(
                TorqueConstraint(np.vstack([Rt @ Ja[:3], Rt @ Ja[3:]]), bias[cols], self.effort_limit[cols], names)
            )
        return out

    def torque_constraint(self, q_cart: Sequence[float] | np.ndarray, u: np.ndarray | None = None) -> TorqueConstraint:
        """Return the first hand's joint-torque constraint (`torque_constraints`)."""
        return self.torque_constraints(q_cart, u)[0]


def push_grasp_rotation(prof: RobotProfile, arm: int = 0) -> np.ndarray:
    """Return R_b_ee of a filled profile's grasp (`push_profile`): its pitch, roll and the arm's tool axis."""
    return grasp_rotation(
        GRASP_PITCH if prof.grasp_pitch is None else prof.grasp_pitch,
        prof.grasp_roll or 0.0,
        prof.arms[arm].tool_axis or "z",
    )


def push_reach_map(robot: str | RobotProfile | robots.LoadedRobot, geometry: CartGeometry | None = None):
    """Return the `ReachMap` along the handle of a robot whose base stands at a fixed place (None otherwise).

    The base stands at ``(handle x + push_base_x, push_base_y)`` in {b}; the continuation starts at y = 0
    from the profile's push posture (or at its fixed contact when the posture was computed there).
    """
    from wholebody.contacts.placement import reach_map

    loaded = robot if isinstance(robot, robots.LoadedRobot) else robots.load(robot)
    prof = push_profile(loaded)
    if prof.push_base_y is None:  # the base follows the contact sideways: every handle point is held alike
        return None
    wb = wholebody_for(loaded, base_input=prof.base_input)
    R = push_grasp_rotation(prof)
    zero = np.zeros(3)
    geo = geometry or DEFAULT_GEOMETRY
    offset = np.array([handle_point(0.0, geo)[0] + prof.push_base_x, prof.push_base_y])
    start = 0.0 if prof.tuned or prof.push_contact_y is None else prof.push_contact_y
    return reach_map(
        wb,
        lambda y: base_target(zero, zero, offset)[0],
        lambda y: grasp_target(zero, zero, float(y), 0.0, R, geo)[0],
        contact_grid() if geometry is None else geo.grid(),
        _filled(prof, "push_seed", prof.push_arm_seed),
        geo.nearest(start),
    )


def base_lateral_places(
    prof: RobotProfile, contact_y: Sequence[float] | np.ndarray, spread: float = TWO_ARM_BASE_SPREAD
) -> list[float]:
    """Return each robot's base y in {b} for contacts `contact_y` (one robot per contact).

    A base with a fixed place (`push_base_y`) stands there when alone; two such robots stand behind their
    own contacts, shifted apart by `spread` each (`side_by_side_spread`). A base that follows its contact stands
    `push_base_dy` beside it (two of them: spread apart as well).
    """
    ys = [float(v) for v in contact_y]
    if len(ys) == 1:
        return [prof.push_base_y if prof.push_base_y is not None else ys[0] + prof.push_base_dy]
    shift = [-spread, spread]
    off = 0.0 if prof.push_base_y is None else prof.push_base_y - _filled(prof, "contact_y", prof.push_contact_y)
    return [y + off + prof.push_base_dy + d for y, d in zip(ys, shift)]


def arms_per_robot(prof: RobotProfile, n_arms: int) -> int:
    """Return how many arms each robot pushes with when `n_arms` hands hold the handle: all of them on one
    base when its profile lists that many arms, else one each (robots side by side)."""
    return n_arms if n_arms > 1 and len(prof.arms) >= n_arms else 1


def multi_arm_placement(robot: robots.LoadedRobot, contact_y: Sequence[float] | np.ndarray):
    """Return the `wholebody.push.posture.MultiArmPlacement` of a robot holding the handle at `contact_y` with
    its first ``len(contact_y)`` arms (grasp, base place, postures by IK; cached per profile and contacts)."""
    return _multi_arm_placement(robot.profile, str(robot.urdf), tuple(float(v) for v in contact_y), _LoadedKey(robot))


@lru_cache(maxsize=32)
def _multi_arm_placement(prof: RobotProfile | None, urdf: str, contact_y: tuple[float, ...], key: _LoadedKey):
    from wholebody.push.posture import solve_multi_arm_placement

    filled = filled_profile(key.robot)
    assert prof is not None  # filled_profile raised otherwise
    wbs = [wholebody_for(key.robot, base_input=prof.base_input, arm=i) for i in range(len(contact_y))]
    return solve_multi_arm_placement(replace(prof, arms=filled.arms), wbs, contact_y)


def multi_arm_reach_maps(robot: robots.LoadedRobot, contact_y: Sequence[float] | np.ndarray, geometry=None) -> tuple:
    """Return one `ReachMap` per hand (in the order of the contacts) of a robot holding the handle at `contact_y`
    with several arms: which handle points each arm holds with margin from the base place `multi_arm_placement`
    found (cached per profile, contacts and geometry)."""
    key = (str(robot.urdf), tuple(float(v) for v in contact_y), geometry)
    return _multi_arm_reach(robot.profile, key, _LoadedKey(robot))


@lru_cache(maxsize=32)
def _multi_arm_reach(prof: RobotProfile | None, key: tuple, loaded: _LoadedKey) -> tuple:
    from wholebody.contacts.placement import reach_map

    _, contact_y, geometry = key
    robot, filled = loaded.robot, filled_profile(loaded.robot)
    pl = multi_arm_placement(robot, contact_y)
    geo = geometry or DEFAULT_GEOMETRY
    zero = np.zeros(3)
    pose = base_target(
        zero, zero, np.array([handle_point(float(np.mean(pl.contact_y)), geo)[0] + pl.base_x, pl.base_y])
    )[0]
    grid = contact_grid() if geometry is None else geo.grid()
    maps = []
    for i, roll, q, y in zip(pl.arms, pl.rolls, pl.postures, pl.contact_y):
        wb = wholebody_for(robot, base_input=filled.base_input, arm=i)
        R = grasp_rotation(pl.pitch, roll, filled.arms[i].tool_axis or "z")

        def target(v: float, R: np.ndarray = R) -> pin.SE3:
            return grasp_target(zero, zero, float(v), 0.0, R, geo)[0]

        maps.append(reach_map(wb, lambda v: pose, target, grid, q, geo.nearest(y)))
    return tuple(maps)


def _multi_arm_robot(
    loaded: robots.LoadedRobot,
    q_cart: np.ndarray,
    contact_y: Sequence[float] | np.ndarray,
    geometry: CartGeometry | None,
    placement_y: Sequence[float] | np.ndarray | None = None,
) -> MobileManipulator:
    """Return one robot holding the handle at every contact, one arm each, from the base place, grasp and postures
    `multi_arm_placement` finds for the contacts `placement_y` (default: `contact_y`)."""
    prof = filled_profile(loaded)
    pl = multi_arm_placement(loaded, contact_y if placement_y is None else placement_y)
    Rs = [grasp_rotation(pl.pitch, r, prof.arms[i].tool_axis or "z") for i, r in zip(pl.arms, pl.rolls)]
    return MobileManipulator(
        loaded,
        q_cart,
        np.sort(np.asarray(contact_y, dtype=float)),  # the arms take the contacts by side, lowest y first
        pl.base_y,
        Rs,
        arm_seed=pl.postures,
        arm=pl.arms,
        geometry=geometry,
        base_x=pl.base_x,
    )


def make_robots(
    robot: str | RobotProfile | robots.LoadedRobot,
    q_cart: np.ndarray,
    contact_y: Sequence[float] | np.ndarray,
    seeds: Sequence[Sequence[float] | np.ndarray | None] | None = None,
    geometry: CartGeometry | None = None,
    placement_y: Sequence[float] | np.ndarray | None = None,
) -> list[MobileManipulator]:
    """Return one mobile manipulator per contact, each holding the handle at its contact (bases spread apart);
    one robot holding every contact when its profile has an arm for each (`arms_per_robot`), placed for the
    contacts `placement_y` (default `contact_y`).

    Everything robot-specific (joints, grasp, base place, seeds) comes from the robot's profile
    (`push_profile`); a posture the IK cannot reach from the place found for one robot is searched again
    (`wholebody.push.placement.arm_posture_near`).
    """
    loaded = robot if isinstance(robot, robots.LoadedRobot) else robots.load(robot)
    if arms_per_robot(filled_profile(loaded), len(contact_y)) > 1:  # one base, its arms each at a contact
        return [_multi_arm_robot(loaded, q_cart, contact_y, geometry, placement_y)]
    prof = push_profile(loaded)
    R_b_ee = push_grasp_rotation(prof)
    # a seed holding NaN (a reach map's posture at a point it does not reach) is no seed
    arm_seeds = [sd if sd is None or np.all(np.isfinite(sd)) else None for sd in list(seeds or ())[: len(contact_y)]]
    arm_seeds += [None] * (len(contact_y) - len(arm_seeds))
    out = []
    places = base_lateral_places(prof, contact_y, side_by_side_spread(loaded, contact_y))
    for y, by, sd in zip(contact_y, places, arm_seeds):
        bx = side_by_side_base_x(loaded, prof, float(by) - float(y)) if len(contact_y) > 1 else None
        try:
            out.append(MobileManipulator(loaded, q_cart, y, by, R_b_ee, arm_seed=sd, geometry=geometry, base_x=bx))
        except WholeBodyError:
            from wholebody.push.posture import arm_posture_near

            wb = wholebody_for(loaded, base_input=prof.base_input)
            seed = arm_posture_near(
                wb, replace(prof, push_base_x=bx or prof.push_base_x), q_cart, float(y), float(by), R_b_ee
            )
            out.append(MobileManipulator(loaded, q_cart, y, by, R_b_ee, arm_seed=seed, geometry=geometry, base_x=bx))
    return out


def base_footprint_box(loaded: robots.LoadedRobot) -> tuple[float, float, float, float] | None:
    """Return (x_min, x_max, y_min, y_max) in m, in the base frame, of the collision geometry fixed to the base's
    planar joint (each geometry's local bounding box, meshes and cylinders included: TIAGo's base is a mesh; the
    wheels, on their own joints, are not in it); None: no such geometry."""
    pts = []
    for g in loaded.collision_model.geometryObjects:
        if g.parentJoint != 1:
            continue
        g.geometry.computeLocalAABB()
        lo, hi = np.asarray(g.geometry.aabb_local.min_), np.asarray(g.geometry.aabb_local.max_)
        corners = np.array(list(itertools.product(*zip(lo, hi))))
        pts.append((corners @ g.placement.rotation.T + g.placement.translation)[:, :2])
    if not pts:
        return None
    xy = np.vstack(pts)
    return float(xy[:, 0].min()), float(xy[:, 0].max()), float(xy[:, 1].min()), float(xy[:, 1].max())


def base_footprint_width(loaded: robots.LoadedRobot) -> float:
    """Return the width (m, along the base's y) of `base_footprint_box` (0: no collision geometry on the base)."""
    box = base_footprint_box(loaded)
    return 0.0 if box is None else box[3] - box[2]


def side_by_side_spread(loaded: robots.LoadedRobot, contact_y: Sequence[float] | np.ndarray) -> float:
    """Return how far (m) each of two robots side by side stands beyond its one-robot place beside its contact: half
    of what the two bases' footprints (`base_footprint_width`) and `BASE_CLEARANCE` need beyond the contacts'
    separation (Ridgeback, 0.79 m wide, at contacts 0.4 m apart: 0.25 m; the 0.6 m wide WMRA: 0.15 m); no less than
    0, `TWO_ARM_BASE_SPREAD` when the URDF gives no base box."""
    width = base_footprint_width(loaded)
    if width <= 0.0:
        return TWO_ARM_BASE_SPREAD
    separation = float(np.ptp(np.asarray(contact_y, dtype=float)))
    return max(0.0, 0.5 * (width + BASE_CLEARANCE - separation))


def side_by_side_base_x(loaded: robots.LoadedRobot, prof: RobotProfile, lateral: float) -> float:
    """Return the base x (relative to the handle, in {b}) of a robot whose base stands `lateral` m beside its contact
    (two robots side by side): the arm's first joint as far from the handle, in the plane, as when the robot pushes
    alone (base `push_base_x` behind the handle, beside its contact as `base_lateral_places` puts one robot), so that
    the arm is no more stretched than the one-arm push posture. The mount's own lateral place on the base counts
    (the WMRA's arm is mounted 0.23 m left of its axle's centre)."""
    wb = wholebody_for(loaded, base_input=prof.base_input)
    data = wb.model.createData()
    pin.forwardKinematics(wb.model, data, wb.to_pinocchio_q(np.zeros(3 + wb.n_arm)))
    mount = data.oMi[wb.model.getJointId(wb.arm_joints[0])].translation  # in the base frame (base at the origin)
    base_x = prof.push_base_x if prof.push_base_x is not None else BASE_OFFSET_X
    alone = (
        prof.push_base_dy
        if prof.push_base_y is None
        else prof.push_base_y - _filled(prof, "contact_y", prof.push_contact_y)
    )
    reach = math.hypot(base_x + mount[0], alone + mount[1])
    side = lateral + mount[1]  # the mount beside the contact
    if abs(side) >= reach:
        return base_x
    return float(-math.sqrt(reach**2 - side**2) - mount[0])


def ft_measurement(
    wrench_world: np.ndarray, oMee: pin.SE3, oMft: pin.SE3, rng: np.random.Generator, noise: MeasurementNoise
) -> pin.Force:
    """Return the F/T sensor reading (sensor frame, at its origin) of a hand wrench, plus white noise."""
    at_origin = pin.SE3(np.eye(3), oMee.translation).act(pin.Force(wrench_world[:3], wrench_world[3:]))
    local = oMft.actInv(at_origin)
    return pin.Force(local.linear + rng.normal(0.0, noise.force, 3), local.angular + rng.normal(0.0, noise.torque, 3))


def ft_to_cart_gamma(reading: pin.Force, oMft: pin.SE3, q_cart_meas: np.ndarray) -> np.ndarray:
    """Return Gamma_MM (fx, fy in {s}, tau about the measured {b} origin) of one F/T reading (eq. 23–24)."""
    world = oMft.act(reading)
    at_b = pin.SE3(np.eye(3), np.array([q_cart_meas[0], q_cart_meas[1], 0.0])).actInv(world)
    return np.array([at_b.linear[0], at_b.linear[1], at_b.angular[2]])
