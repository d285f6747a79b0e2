"""Settings, results and swap-in interfaces of the closed push loop (`wholebody.push.loop.run_push`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np
import pinocchio as pin

from cart.control import ControllerName as CartControllerName
from cart.params import CartParams
from cart.simulate import MeasurementNoise
from cart.trajectories import CartTrajectory, paper_trajectory
from wholebody.contacts.allocation import ArmLimits, GraspModel
from wholebody.contacts.support import SupportPolygon
from wholebody.errors import WholeBodyError
from wholebody.push.base_settings import BasePlanSettings
from wholebody.push.file_version import file_version
from wholebody.push.geometry import DEFAULT_GEOMETRY, CartGeometry
from wholebody.push.load_change import LoadChange, check_changes
from wholebody.push.reference_clock import TimeScaling

if TYPE_CHECKING:
    from wholebody.push.cart_file import CartSource

#: How the contact points are chosen: held at `fixed_contact_y`, or re-planned from the estimate.
ContactMode = Literal["fixed", "optimal"]
#: The parameter estimator of the loop: the online least squares (`cart.online_estimator`) or the paper's EKF.
EstimatorName = Literal["online", "ekf"]
#: What answers the controller: ideal servos and the exact cart model, or robots and cart in MuJoCo.
PlantName = Literal["kinematic", "mujoco"]

#: The simulated cart of the default scenario (paper Table I test 5: 20 kg, CoM (0.3, 0.15)); I scaled
#: from the shopping cart of `robots` (1.7355 kg m^2 at 15 kg); viscous coefficient 4 N s/m.
TRUE_CART = CartParams(m=20.0, dx=0.3, dy=0.15, I=1.7355 * 20.0 / 15.0, sigma=4.0)


class CartController(Protocol):
    """Cart tracking law: desired Gamma_MM = (fx, fy in {s}, tau about the {b} origin)."""

    def gamma(self, t: float, q: np.ndarray, qd: np.ndarray, params: CartParams) -> np.ndarray:
        """Return the desired generalized force."""


class ParameterEstimator(Protocol):
    """State + parameter estimator fed with the applied wrench and the motion-capture measurement."""

    @property
    def x(self) -> np.ndarray:
        """Return the state estimate, first (x, y, theta, vx, vy, omega) (read only: an attribute or a property)."""

    def step(self, gamma: np.ndarray, dt: float, z: np.ndarray) -> float:
        """Predict over dt under gamma, then update with z = (x, y, theta, vx, vy, omega)."""

    def params(self) -> CartParams:
        """Return the current parameter estimate."""


class BodyTracker(Protocol):
    """Whole-body velocity controller of one mobile manipulator."""

    def step(
        self,
        x: np.ndarray,
        target: pin.SE3,
        target_velocity: np.ndarray,
        base_target: np.ndarray,
        base_velocity: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """Return the input u = [arm joint rates (7), base body twist (3)] for the next period."""


#: Sensor noise of the loop: motion capture (3 mm, 3 mrad, 1 cm/s, 0.01 rad/s) and the F/T sensor
#: (3 N, 0.3 N m, in the sensor frame), as the cart paper's hardware.
PUSH_SENSOR_NOISE = MeasurementNoise(position=0.003, theta=0.003, velocity=0.01, omega=0.01, force=3.0, torque=0.3)


#: the grip's squeeze (N per finger) of an arm whose profile gives no ``grip_force`` (docs/robots.md)
PUSH_GRIP_FORCE = 200.0
#: the push loop's hand limits: `ArmLimits` with a `PUSH_GRIP_FORCE` grip (`PushConfig.arm_limits`)
PUSH_ARM_LIMITS = ArmLimits(grasp=GraspModel(grip_force=PUSH_GRIP_FORCE))


@dataclass(frozen=True)
class PushConfig:
    """One closed-loop run: trajectory, robots, contact mode, estimator, truth, noise, seed."""

    #: the paper's Traj. 1 or 2, or any desired cart motion (`cart.trajectories.WaypointTrajectory`,
    #: `FunctionTrajectory`, or an object with ``duration`` and ``sample(t) -> (q, qd, qdd)``)
    trajectory: int | CartTrajectory = 2
    duration: float = 30.0
    dt: float = 0.01
    substeps: int = 2
    n_arms: int = 1
    estimation: bool = True
    #: which estimator runs when `estimation` is on (`wholebody.push.loop.make_estimator`)
    estimator: EstimatorName = "online"
    contact: ContactMode = "optimal"
    #: fixed contact point(s) y (m); None = the robot's `push_contact_y` (two arms: -0.2, 0.2)
    fixed_contact_y: tuple[float, ...] | None = None
    true_params: CartParams = TRUE_CART
    initial_mass: float = 16.0
    initial_com: tuple[float, float] = (0.3, 0.0)
    controller: CartControllerName = "kanayama"
    noise: MeasurementNoise = PUSH_SENSOR_NOISE
    seed: int = 0
    #: the plant the controller drives (`wholebody.push.plants.make_plant`)
    plant: PlantName = "kinematic"
    #: MuJoCo plant: an MJCF cart file following docs/mujoco.md (None: the shopping cart built from true_params)
    cart_model: str | None = None
    #: where the hands may hold and how high {b} sits (None: the shopping cart's, or the cart file's)
    geometry: CartGeometry | None = None
    replan_period: float = 0.5
    replan_horizon: float = 3.0
    slide_speed: float = 0.05
    #: contact slide acceleration (m/s^2): the hand's speed along the handle changes smoothly
    slide_acceleration: float = 0.1
    #: each hand's limits (`hand_limits`: the grip force of an arm whose profile gives ``grip_force`` is the
    #: profile's); the grasp squeezes 200 N per finger (the 2F-85 holds 20-235 N): one hand then makes
    #: 8 N m of yaw torque at its 0.02 m torque arm. A turn's yaw torque comes from the grip's torque and from
    #: lateral force at the handle, which the tip-over bound limits (all the more with `tip_std_factor`'s margin):
    #: at 150 N the Ridgeback's MuJoCo Traj. 2 saturates on the grip's torque in the turns (seed 2: 1.44 s), the
    #: cart's unmodelled dynamics there read as mass (21.87 kg for m_eff 20.70); at 200 N 0.53 s, 21.26 kg.
    #: At 100 N only seed 0 holds the second turn (docs/mujoco.md "Why Traj. 2 diverges")
    arm_limits: ArmLimits = PUSH_ARM_LIMITS
    #: the pushing robot: a registered name or the path of a robot profile (.toml), see docs/robots.md
    robot: str = "ridgeback_iiwa"
    #: the allocation keeps each joint torque |J^T w + g| this fraction below its URDF limit (room for the
    #: dynamic terms); None = joint torques not bounded in the allocation
    torque_margin: float | None = 0.05
    #: plan each holonomic base's place ahead over the desired motion within its wheel speeds, heading free
    #: (`wholebody.push.base_plan`); None = each base held rigidly behind its contact; "auto" = planned on the
    #: MuJoCo plant, whose wheels have their limits (`plan_settings`), not on the kinematic one
    base_plan: BasePlanSettings | Literal["auto"] | None = "auto"
    #: keep every wheel of the cart loaded (`wholebody.contacts.support`): the allocation bounds the hands' moments
    #: about the cart's support edges and lets the hands press down on the handle (spatial hand wrenches); False =
    #: planar hand wrenches, pushed sideways as hard as the allocation likes; "auto" = on the MuJoCo plant, whose
    #: cart can tip (`tip_on`), not on the kinematic one, whose rigid planar cart cannot (and whose sliding
    #: contact's scheduler does not know the bound: Traj. 2 with it is lost in the second turn, docs/mujoco.md)
    tip_bound: bool | Literal["auto"] = "auto"
    #: the bound takes the estimate's mass and CoM less this many of their 1-sigma, on the support edges the hands
    #: are inside of (`wholebody.contacts.support.holding_moment`). 0: the estimate as it is (the WMRA's MuJoCo
    #: Traj. 2, seed 0, then tips the cart: the CoM's y estimate 0.075 m, 1-sigma 0.015 m, truth 0.15 m); 3: with a
    #: 150 N grip the Ridgeback's Traj. 2 (seed 0) mass estimate ends 6.5 % off (docs/mujoco.md). The margin's
    #: press on the handle does not read as mass (a constant 30 N press without it: seed 2 21.16 -> 21.14 kg)
    tip_std_factor: float = 1.5
    #: the cart's floor contacts for that bound (None: the default cart's, or the cart file's wheels)
    support: SupportPolygon | None = None
    #: slow the desired motion down while the allocation cannot give its wrench (`wholebody.push.reference_clock`):
    #: the cart follows the desired path later instead of being lost; None = the desired timing however it saturates;
    #: "auto" = on the MuJoCo plant (whose arms, grips and cart have the limits that bind), not on the kinematic one
    time_scaling: TimeScaling | Literal["auto"] | None = "auto"
    #: loads put into the cart or taken out of it during the run (`wholebody.push.load_change`): the plant's cart
    #: changes at each, the estimate is judged against the truth at each instant
    load_changes: tuple[LoadChange, ...] = ()

    def __post_init__(self) -> None:
        if isinstance(self.trajectory, int) and self.trajectory not in (1, 2):
            raise WholeBodyError(f"trajectory must be 1, 2 or a trajectory object, got {self.trajectory}")
        if not isinstance(self.trajectory, int) and not callable(getattr(self.trajectory, "sample", None)):
            raise WholeBodyError("trajectory must be 1, 2 or an object with sample(t) -> (q, qd, qdd)")
        if self.n_arms not in (1, 2):
            raise WholeBodyError(f"arms must be 1 or 2, got {self.n_arms}")
        if self.estimator not in ("online", "ekf"):
            raise WholeBodyError(f"estimator must be 'online' or 'ekf', got {self.estimator!r}")
        if self.plant not in ("kinematic", "mujoco"):
            raise WholeBodyError(f"plant must be 'kinematic' or 'mujoco', got {self.plant!r}")
        if self.cart_model is not None and self.plant != "mujoco":
            raise WholeBodyError("a cart model file needs the MuJoCo plant (plant='mujoco')")
        if self.plant == "mujoco" and self.contact != "fixed":
            raise WholeBodyError("the MuJoCo plant's grips are welds that cannot slide: use contact='fixed'")
        if self.contact not in ("fixed", "optimal"):
            raise WholeBodyError(f"contact must be 'fixed' or 'optimal', got {self.contact!r}")
        if not (self.dt > 0 and self.duration > 0 and self.initial_mass > 0):
            raise WholeBodyError("dt, duration and initial_mass must be positive")
        if len(self.initial_com) != 2 or not np.all(np.isfinite(np.asarray(self.initial_com, dtype=float))):
            raise WholeBodyError(f"initial_com must be (dx, dy) in m, finite, got {self.initial_com!r}")
        from robots.profiles import profile

        prof = profile(self.robot)  # raises naming the known robots
        if not prof.is_mobile_manipulator:
            raise WholeBodyError(f"robot {self.robot!r} cannot push the cart: its profile has no arm on a wheeled base")
        if self.plant == "mujoco" and 1 < self.n_arms <= len(prof.arms):  # one base, several arms
            raise WholeBodyError(
                f"the MuJoCo plant drives one arm per robot; robot {prof.name!r} pushes with its {self.n_arms} arms "
                "on the kinematic plant (plant='kinematic', --plant kinematic) or with one (n_arms=1, --arms 1)"
            )
        if not (self.base_plan is None or self.base_plan == "auto" or isinstance(self.base_plan, BasePlanSettings)):
            raise WholeBodyError(f"base_plan must be BasePlanSettings, 'auto' or None, got {self.base_plan!r}")
        if not (self.tip_bound in (True, False, "auto") and self.tip_std_factor >= 0.0):
            raise WholeBodyError("tip_bound must be True, False or 'auto' and tip_std_factor >= 0")
        if not (self.time_scaling is None or self.time_scaling == "auto" or isinstance(self.time_scaling, TimeScaling)):
            raise WholeBodyError(f"time_scaling must be TimeScaling, 'auto' or None, got {self.time_scaling!r}")
        if self.fixed_contact_y is not None and len(self.fixed_contact_y) not in (1, 2):
            raise WholeBodyError("fixed_contact_y needs one value per arm")
        if not all(isinstance(c, LoadChange) for c in self.load_changes):
            raise WholeBodyError("load_changes must be a tuple of LoadChange")
        # what a cart file's loads take out is the plant's to check (`MujocoPlant`); times, places, masses here
        check_load_changes(self.load_changes, self.duration, self.true_params, self.cart_model)

    def hand_limits(self, arms: Sequence[int] | None = None) -> tuple[ArmLimits, ...]:
        """Return each hand's limits: `arm_limits` with the grip force of the hand's arm when its robot profile gives
        one (``grip_force`` in its ``[[arms]]`` table: the robot's own gripper). `arms`: the profile's arm of each
        hand, in contact order (`MobileManipulator.arms` of the robots in turn); None: arm 0 of each robot, or arms
        0, 1 of one robot that pushes with both (`wholebody.push.robot.arms_per_robot`)."""
        from robots.profiles import profile

        prof = profile(self.robot)
        if arms is None:
            from wholebody.push.robot import arms_per_robot

            arms = [hand % arms_per_robot(prof, self.n_arms) for hand in range(self.n_arms)]
        lim = self.arm_limits
        forces = [prof.arms[a].grip_force for a in arms]
        return tuple(
            lim if f is None else replace(lim, grasp=replace(lim.grasp or GraspModel(), grip_force=f)) for f in forces
        )

    def contact_y0(self) -> np.ndarray:
        """Return the initial contact y per arm (fixed mode: the fixed points)."""
        from robots.profiles import profile

        y0 = profile(self.robot).push_contact_y
        given = self.fixed_contact_y if self.fixed_contact_y is not None else (0.0 if y0 is None else y0,)
        ys = np.asarray(given, dtype=float)
        if self.n_arms == 2 and ys.size == 1:
            ys = np.array([-0.2, 0.2])
        if self.n_arms == 1:
            ys = ys[:1]
        geo = self.cart_geometry()
        if geo is DEFAULT_GEOMETRY:
            _check_on_handle(ys, geo, "fixed_contact_y" if self.fixed_contact_y is not None else "[push] contact_y")
        if self.n_arms == 2 and geo.grips is not None and len(set(geo.grips)) < 2:
            where = "the cart file's" if self.cart_model is not None else "the geometry's"
            raise WholeBodyError(
                f"{where} handle is one grip point (y = {geo.grips[0]:g} m): two arms need two grips or a bar across "
                "the cart (docs/mujoco.md); push with one arm (n_arms=1, --arms 1)"
            )
        if geo is not DEFAULT_GEOMETRY:  # a cart of its own: the nearest places its handle offers
            ys = np.array([geo.nearest(v) for v in ys])
            if ys.size == 2 and abs(ys[1] - ys[0]) < 0.2:  # two hands need room: the outermost places
                ys = geo.grid()[[0, -1]]
        return np.sort(ys)

    def cart_geometry(self) -> CartGeometry:
        """Return the cart geometry the controller is told: given, read from the cart file, or the default."""
        if self.geometry is not None:
            return self.geometry
        if self.cart_model is not None:
            return _file_geometry(self.cart_model)
        return DEFAULT_GEOMETRY

    def plan_settings(self) -> BasePlanSettings | None:
        """Return the base plan's settings this run uses: given, None, or for "auto" the defaults on the MuJoCo plant."""
        if self.base_plan == "auto":
            return BasePlanSettings() if self.plant == "mujoco" else None
        return self.base_plan

    def scaling_settings(self) -> TimeScaling | None:
        """Return the reference's time scaling this run uses: given, None, or for "auto" the defaults on the MuJoCo plant."""
        if self.time_scaling == "auto":
            return TimeScaling() if self.plant == "mujoco" else None
        return self.time_scaling

    def tip_on(self) -> bool:
        """Return whether the allocation keeps the cart's wheels loaded: given, or for "auto" on the MuJoCo plant."""
        return self.plant == "mujoco" if self.tip_bound == "auto" else bool(self.tip_bound)

    def support_polygon(self) -> SupportPolygon | None:
        """Return the cart's support for the tip-over bound: given, the cart file's wheels, or the default cart's."""
        if self.support is not None:
            return self.support
        from wholebody.push.tip_support import cart_file_support, shopping_cart_support

        if self.cart_model is not None:
            return cart_file_support(self.cart_model, self.cart_geometry())
        return shopping_cart_support(self.cart_geometry())

    def initial_params(self) -> CartParams:
        """Return the controller's/estimator's initial guess (mass, CoM given; inertia scaled with the mass)."""
        return CartParams(
            self.initial_mass,
            self.initial_com[0],
            self.initial_com[1],
            self.true_params.I * self.initial_mass / self.true_params.m,
            self.true_params.sigma,
        )

    def make_trajectory(self) -> CartTrajectory:
        """Return the desired cart motion: Traj. 1 or 2 of the paper with this run's duration, or the given one."""
        if isinstance(self.trajectory, int):
            return paper_trajectory(self.trajectory, self.duration)
        return self.trajectory

    @property
    def trajectory_label(self) -> str:
        """Return a short name of the trajectory ("Traj. 2", or the object's class name)."""
        return f"Traj. {self.trajectory}" if isinstance(self.trajectory, int) else type(self.trajectory).__name__


#: the lightest and the heaviest cart a push handles (kg; loads put in included; ``--initial-mass``'s range): a
#: cart file's checks (`cart_file`) and the load changes' (`check_load_changes`)
CART_MASS_RANGE_KG = (0.1, 1e4)


def check_load_changes(
    changes: Sequence[LoadChange],
    duration: float,
    true_params: CartParams = TRUE_CART,
    cart_model: str | None = None,
) -> None:
    """Raise WholeBodyError when a load change falls outside (0, duration), is put in or taken out at a place off the
    cart (outside its plan extent: `cart_file.plan_extent` of the cart file, or of the shopping cart the kinematic
    and MuJoCo plants push), makes the cart heavier than `CART_MASS_RANGE_KG`, or takes out more than the cart
    `true_params` holds (a cart file's: the plant checks it)."""
    check_changes(None, changes, duration)
    if not changes:
        return
    label, mass, extent = _cart_bounds(cart_model)
    if cart_model is None:
        mass = true_params.m
    x0, x1, y0, y1 = extent
    for c in changes:
        if c.xy is not None and not (x0 <= c.xy[0] <= x1 and y0 <= c.xy[1] <= y1):
            verb = f"puts {c.mass:g} kg in" if c.mass > 0 else f"takes {-c.mass:g} kg out"
            raise WholeBodyError(
                f"the load change at t = {c.t:g} s {verb} at ({c.xy[0]:g}, {c.xy[1]:g}) m in {{b}}, off the cart: "
                f"{label} spans x in [{x0:.3f}, {x1:.3f}] m and y in [{y0:.3f}, {y1:.3f}] m"
            )
    hi = CART_MASS_RANGE_KG[1]
    total = mass
    for c in sorted(changes, key=lambda c: c.t):
        total += c.mass
        if total > hi:
            raise WholeBodyError(
                f"the load change at t = {c.t:g} s puts {c.mass:g} kg in, making the {mass:g} kg cart {total:g} kg "
                f"with the loads before it; a push handles carts of at most {hi:g} kg"
            )
    check_changes(true_params if cart_model is None else None, changes, duration)


def _check_on_handle(ys: np.ndarray, geo: CartGeometry, source: str) -> None:
    """Raise WholeBodyError when a fixed contact y lies off the handle's span (`CartGeometry.y_range`)."""
    lo, hi = geo.y_range
    off = [float(y) for y in ys if not lo - 1e-9 <= y <= hi + 1e-9]
    if off:
        raise WholeBodyError(
            f"{source}: contact y = {off[0]:g} m is off the cart's handle, which spans y in [{lo:g}, {hi:g}] m "
            "in the cart frame {b}; give a contact point on it"
        )


def _cart_bounds(cart_model: str | None) -> tuple[str, float, tuple[float, float, float, float]]:
    """Return (a label, mass kg, plan extent in {b}) of the cart a push pushes: the cart file's, or the shopping
    cart's (the kinematic plant's cart has its dimensions, `robots.shopping_cart`)."""
    source = _shopping_cart_source() if cart_model is None else _file_source(cart_model, file_version(cart_model))
    if source.extent is None or source.mass is None:
        raise WholeBodyError(f"cart {source.label}: its extent and mass are not known")
    return ("the shopping cart" if cart_model is None else f"cart {cart_model}"), source.mass, source.extent


@lru_cache(maxsize=1)
def _shopping_cart_source() -> CartSource:
    """Return the `CartSource` of the shopping cart (its geometry does not depend on its inertial parameters)."""
    from wholebody.push.cart_file import cart_source

    return cart_source(TRUE_CART)


@lru_cache(maxsize=8)
def _file_source(path: str, version: tuple[int, int] | None) -> CartSource:
    """Return the `CartSource` of a cart file (`version`: its modification time and size, the cache's key)."""
    from wholebody.push.cart_file import load_cart_file

    return load_cart_file(path)


#: a cart this far (m) from its desired place is lost: the run reports when (`PushMetrics.tracking_lost_at_s`)
LOST_TRACKING_M = 0.25


def _file_geometry(path: str) -> CartGeometry:
    """Return the geometry of a cart file, read once per version of the file (an edited file is read again)."""
    return _geometry_of(path, file_version(path))


@lru_cache(maxsize=8)
def _geometry_of(path: str, version: tuple[int, int] | None) -> CartGeometry:
    """Return the geometry of a cart file (`version`: its modification time and size, the cache's key)."""
    from wholebody.push.geometry import geometry_from_cart_file

    return geometry_from_cart_file(path)


@dataclass(frozen=True)
class PushMetrics:
    """Scalar results of one run (the CLI's JSON fields)."""

    #: cart tracking error of the {b} origin vs the desired one (mm)
    tracking_rms_mm: float
    tracking_max_mm: float
    arm_torque_rms_nm: float
    arm_torque_peak_nm: float
    arm_push_torque_rms_nm: float
    arm_torque_limit_ratio: float
    ee_force_rms_n: float
    ee_force_peak_n: float
    ee_torque_rms_nm: float
    mass_error_final_kg: float
    com_error_final_m: float
    mass_final_kg: float
    grasp_error_max_m: float
    base_twist_limit_ratio: float
    base_wheel_limit_ratio: float
    saturated_steps: int
    base_wheel_speed_rms_rad_s: float = 0.0
    base_wheel_speed_max_rad_s: float = 0.0
    base_wheel_acceleration_max_rad_s2: float = 0.0
    base_lateral_speed_max_m_s: float = 0.0
    #: largest change of one arm joint torque between two samples (N m)
    arm_torque_step_max_nm: float = 0.0
    mass_error_rms_kg: float = 0.0
    mass_error_max_after_5s_kg: float = 0.0
    com_error_rms_m: float = 0.0
    com_error_max_after_5s_m: float = 0.0
    time_mass_within_1kg_s: float = 0.0
    time_com_within_1cm_s: float = 0.0
    #: stretches [t0, t1] (s) over which the EKF's 1-sigma of the mass / CoM grew for >= 1 s: the pushes
    #: carried less information about it than the filter's random walk adds (`unobservable_intervals`)
    mass_unobservable_s: tuple[tuple[float, float], ...] = ()
    com_unobservable_s: tuple[tuple[float, float], ...] = ()
    #: first time (s) the cart is more than `LOST_TRACKING_M` from its desired place (None: never): the loop lost it
    tracking_lost_at_s: float | None = None
    #: where the allocation saturated: per binding limit, total time, number of stretches, longest stretch
    #: and first time (s) (`wholebody.contacts.allocation.saturation_summary`)
    saturation: dict = field(default_factory=dict)
    #: the slowest rate of the reference's time (`wholebody.push.reference_clock`; 1: never slowed), the time
    #: (s) it ran slower than the desired motion, and how far (s) behind the desired motion it ends; the tracking
    #: error is measured against this reference (the one the controller followed)
    reference_time_scale_min: float = 1.0
    reference_slowed_s: float = 0.0
    reference_delay_s: float = 0.0

    def as_dict(self) -> dict:
        """Return the metrics as a JSON-ready dict (intervals as lists of [t0, t1])."""
        return {k: (v if k == "saturation" else _json_value(v)) for k, v in self.__dict__.items()}


def _json_value(v: float | tuple[tuple[float, float], ...] | None) -> int | float | list[list[float]] | None:
    """Return a metric as int, float, None or a list of [t0, t1] lists."""
    if v is None:
        return None
    if isinstance(v, tuple):
        return [[float(a), float(b)] for a, b in v]
    return int(v) if isinstance(v, (int, np.integer)) else float(v)


@dataclass(frozen=True)
class PushResult:
    """Time histories of one run (N samples at t_k = k dt) and its metrics."""

    config: PushConfig
    t: np.ndarray
    q_true: np.ndarray  # (N, 3) cart pose
    qd_true: np.ndarray
    q_desired: np.ndarray
    z_meas: np.ndarray  # (N, 6) motion capture
    gamma_desired: np.ndarray  # (N, 3) controller output
    gamma_applied: np.ndarray  # (N, 3) produced by the hands (true)
    gamma_measured: np.ndarray  # (N, 3) from the F/T sensors through the grasp map
    phi_hat: np.ndarray  # (N, 4) estimate used by the controller at t_k
    contact_y: np.ndarray  # (N, n_arms)
    wrenches: np.ndarray  # (N, n_arms, 6) hand wrenches in {a}
    arm_torque: np.ndarray  # (N, n_arms, 7)
    push_torque: np.ndarray  # (N, n_arms, 7) the J^T w part
    robot_x: np.ndarray  # (N, n_arms, 10) base pose + arm joints
    grasp_error: np.ndarray  # (N, n_arms) ee position error w.r.t. the handle point
    effort_limit: np.ndarray  # (n_joints,), or (n_arms, n_joints) when the hands' arms differ (`loop.effort_limits`)
    metrics: PushMetrics
    base_twist: np.ndarray | None = None  # (N, n_arms, 3) base body twist (vx, vy, wz)
    wheel_rates: np.ndarray | None = None  # (N, n_arms, n_wheels) rad/s
    wheel_velocity_limit: np.ndarray | None = None  # (n_wheels,) rad/s
    #: (N, 4) the estimator's 1-sigma of the mass (kg), of the CoM (m, norm over dx, dy), of dx and of dy (m) at t_k;
    #: NaN when the estimator gives no covariance
    param_std: np.ndarray | None = None
    #: the plant's own diagnostics (`wholebody.push.plants.plant_report`): "plant", and for MuJoCo the cart's
    #: true and effective mass, wrench error, grasp and wheel slip, real-time factor
    plant_report: dict | None = None
    #: what the estimator says of its run (`cart.online_estimator.OnlineLSEstimator.report`): load changes
    #: (time, new mass), run-off flags, parameters the motion did not excite; {} for the paper's EKF
    estimator_report: dict | None = None
    #: the profile's arms each robot drives, in the order of its state's arm joints (one base with several arms:
    #: more than one; `wholebody.push.robot.MobileManipulator.arms`)
    robot_arms: tuple[int, ...] = (0,)
    #: (N,) the reference time s at t_k and its rate ds/dt (`wholebody.push.reference_clock`); q_desired = q_d(s)
    reference_time: np.ndarray | None = None
    reference_rate: np.ndarray | None = None
    #: (N, 5) the truth the estimate is judged against at t_k: m, dx, dy, I, sigma (`wholebody.push.load_change`:
    #: it steps at each load change); None: ``config.true_params`` throughout
    params_true: np.ndarray | None = None
    #: the load changes the plant made (`PushConfig.load_changes`), each with the time it took effect and the
    #: truth's mass before and after (on the MuJoCo plant the effective mass): JSON-ready dicts
    load_changes_true: tuple[dict, ...] = ()
    #: what the set-up changed in the configuration (`wholebody.push.loop.held_default_contact`): sentences
    setup_notes: tuple[str, ...] = ()

    def truth(self) -> np.ndarray:
        """Return (N, 5) m, dx, dy, I, sigma of the truth at each t_k (`params_true`, or the constant truth)."""
        if self.params_true is not None:
            return self.params_true
        p = self.config.true_params
        return np.tile([p.m, p.dx, p.dy, p.I, p.sigma], (len(self.t), 1))
