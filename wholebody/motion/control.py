"""Resolved-rate end-effector control as a QP per step (paper eq. 21 with limits, §VI safety band).

Each step solves, over the input ``u = [arm rates, base input]``::

    min  ||J u - (v_d + K e)||_W^2 + damping ||u||^2 + secondary(u)
         [+ base_weight ||M u_b - (vb_d + K_b e_b)||^2  when a base target is given]
    s.t. joint position limits (as rate bounds over dt), joint and wheel speed limits,
         optional wheel acceleration limit and safety band: the base origin stays inside a disc.

The QP is composed from `Task`s (`wholebody.motion.tasks`) and `Limit`s (`wholebody.motion.limits`)
that `ResolvedRateController` builds from its `ControllerConfig`; extra ones can be passed in.
`u = 0` always satisfies the built-in constraints (bounds are relaxed to contain 0), so the
QP is feasible; if the solver fails anyway the step returns zero motion and says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import qpsolvers

from wholebody.errors import WholeBodyError
from wholebody.motion.kernels import reference_twist, residual_norm
from wholebody.motion.kinematics import WholeBody
from wholebody.motion.limits import (
    JointPositionLimit,
    JointVelocityLimit,
    SafetyBand,
    SafetyBandLimit,
    WheelAccelerationLimit,
    WheelVelocityLimit,
)
from wholebody.qp import DaqpSolver, ProxQPSolver
from wholebody.motion.qp import (
    DirectSolver,
    Limit,
    QPWorkspace,
    SolverChoice,
    StepState,
    Task,
    solve_step,
    stack_box,
    stack_inequalities,
)
from wholebody.motion.tasks import (
    BaseTask,
    DampingTask,
    EndEffectorTask,
    ManipulabilityTask,
    PostureTask,
    manipulability,
    manipulability_gradient,
    pose_error,
)

__all__ = [
    "ControllerConfig",
    "ResolvedRateController",
    "SafetyBand",
    "StepResult",
    "default_limits",
    "default_tasks",
    "manipulability",
    "manipulability_gradient",
    "pose_error",
]


@dataclass(frozen=True)
class ControllerConfig:
    """Weights, gains and options of the resolved-rate QP.

    Attributes:
        gain: pose-error feedback K (1/s).
        position_weight, orientation_weight: task weights W (per m/s, per rad/s).
        damping: Levenberg damping on ||u||^2 (keeps singular steps bounded).
        secondary: "posture" (pull the arm to `posture`), "manipulability" (ascend the arm's
            manipulability), or "none".
        secondary_weight: weight of the secondary objective.
        posture_gain: rate (1/s) of the posture pull.
        posture: arm posture to pull to; None = the arm posture at the controller's creation.
        max_linear_speed, max_angular_speed: bound on the commanded EE twist (m/s, rad/s).
        limit_margin: joint position limits are shrunk by this much (rad).
        singular_threshold: a step is flagged singular when sigma_min(J) is below this.
        residual_tolerance: a step is flagged saturated when ||J u - v_ref|| exceeds this.
        solver: a `qpsolvers` solver name. "daqp" (default) and "proxqp" are called directly
            (`wholebody.qp.DaqpSolver`: daqp's active-set solve of each step's QP, exact to rounding and
            independent of earlier steps; `ProxQPSolver`: one dense ProxQP problem updated in place each step),
            any other through `qpsolvers`.
        solver_tolerance: absolute tolerance passed to proxqp (its default 1e-5 perturbs the
            rates by ~1e-4 rad/s); other solvers use their defaults.
        warm_start: for solver "proxqp": True (default) starts each solve from the previous solution and keeps
            its first preconditioner (faster; u moves within the solver tolerance along nearly free directions,
            up to ~2e-3 on ill-conditioned steps, while the QP cost and J u stay within ~1e-6 of the
            optimum); False reproduces a fresh proxqp solve. Other solvers ignore it.
        fallback_solver: `qpsolvers` solver tried when `solver` returns nothing (an active-set or interior
            solver can fail on degenerate active sets, e.g. a safety band pinning the base's forward speed to 0
            from both sides), or None.
        base_weight: weight of the optional base regularisation ||M u_b - t*||^2 (M: base input ->
            body twist, t*: body twist steering the base to the `base_target` passed to `step`);
            0 (default) or no `base_target` = off.
        base_gain: rate (1/s) of the pull of the base to its target pose.
        base_lookahead: > 0 (m): the base term tracks a look-ahead point at body offset (base_lookahead, 0)
            towards the same point of the target pose instead of the pose (paper 2 section VI; the point's
            velocity is fully actuated on a differential drive, so the base follows without sliding sideways).
        wheel_acceleration_limit: wheel-rate change per second (rad/s^2) allowed between steps of a base driven
            by wheel rates; None = no limit.
    """

    gain: float = 20.0
    position_weight: float = 1.0
    orientation_weight: float = 1.0
    damping: float = 1e-6
    secondary: str = "posture"
    secondary_weight: float = 1e-3
    posture_gain: float = 1.0
    posture: tuple[float, ...] | None = None
    max_linear_speed: float = 1.0
    max_angular_speed: float = 1.5
    limit_margin: float = 0.0
    singular_threshold: float = 1e-3
    residual_tolerance: float = 1e-3
    solver: str = "daqp"
    fallback_solver: str | None = "proxqp"
    solver_tolerance: float = 1e-9
    base_weight: float = 0.0
    base_gain: float = 2.0
    base_lookahead: float = 0.0
    wheel_acceleration_limit: float | None = None
    warm_start: bool = True

    def __post_init__(self) -> None:
        if not (self.base_weight >= 0 and self.base_gain >= 0 and self.base_lookahead >= 0):
            raise WholeBodyError("base_weight, base_gain and base_lookahead must be >= 0")
        if self.wheel_acceleration_limit is not None and not self.wheel_acceleration_limit > 0:
            raise WholeBodyError(f"wheel_acceleration_limit must be positive, got {self.wheel_acceleration_limit}")
        if self.secondary not in ("posture", "manipulability", "none"):
            raise WholeBodyError(f"secondary must be posture, manipulability or none, got {self.secondary!r}")
        if self.solver not in qpsolvers.available_solvers:
            raise WholeBodyError(f"QP solver {self.solver!r} not installed; available: {qpsolvers.available_solvers}")
        if self.fallback_solver is not None and self.fallback_solver not in qpsolvers.available_solvers:
            raise WholeBodyError(f"fallback QP solver {self.fallback_solver!r} not installed")


@dataclass
class StepResult:
    """One control step: the input and what happened (a plain dataclass: built every step, cheaply).

    Attributes:
        u: input [arm rates, base input] to apply for dt (finite, within the limits).
        position_error, orientation_error: pose error before the step (m, rad).
        residual: ||J u - v_ref|| (task velocity not achieved).
        saturated: residual > tolerance (limits or singularity prevented the commanded motion).
        solver_ok: False if every QP solver failed (then u = 0).
        fallback_used: True if the primary solver failed and the fallback solved the step.
        jacobian: the combined Jacobian J (6 x n_u) of the step.
        singular_threshold: threshold of `singular`.
        sigma_min: smallest singular value of J (computed on first access: an SVD, not paid by steps
            whose caller does not read it).
        singular: sigma_min < singular_threshold.
    """

    u: np.ndarray
    position_error: float
    orientation_error: float
    residual: float
    saturated: bool
    solver_ok: bool
    fallback_used: bool = False
    jacobian: np.ndarray = field(default_factory=lambda: np.zeros((6, 0)), repr=False)
    singular_threshold: float = 1e-3

    @cached_property
    def sigma_min(self) -> float:
        """Smallest singular value of the step's combined Jacobian."""
        return float(np.linalg.svd(self.jacobian, compute_uv=False)[-1])

    @property
    def singular(self) -> bool:
        """True if sigma_min < singular_threshold."""
        return bool(self.sigma_min < self.singular_threshold)


def direct_solver(config: ControllerConfig) -> DirectSolver | str:
    """Return the primary solver of a config: daqp or ProxQP called directly, else the `qpsolvers` name."""
    if config.solver == "daqp":
        return DaqpSolver()
    if config.solver == "proxqp":
        return ProxQPSolver(config.solver_tolerance, config.warm_start)
    return config.solver


def default_tasks(wb: WholeBody, config: ControllerConfig, posture: np.ndarray | None) -> list[Task]:
    """Return the tasks of a config: end-effector, damping, the secondary objective, the base term."""
    tasks: list[Task] = [
        EndEffectorTask(np.r_[np.full(3, config.position_weight), np.full(3, config.orientation_weight)]),
        DampingTask(wb.n_u, config.damping),
    ]
    if config.secondary == "posture":
        tasks.append(PostureTask(wb, config.secondary_weight, config.posture_gain, posture))
    elif config.secondary == "manipulability":
        tasks.append(ManipulabilityTask(config.secondary_weight))
    if config.base_weight > 0:
        tasks.append(BaseTask(config.base_weight, config.base_gain, config.base_lookahead))
    return tasks


def default_limits(wb: WholeBody, config: ControllerConfig, band: SafetyBand | None) -> list[Limit]:
    """Return the limits of a config: joint positions and speeds, wheel speeds and accelerations, the band."""
    limits: list[Limit] = [JointPositionLimit(wb, config.limit_margin), JointVelocityLimit(wb), WheelVelocityLimit(wb)]
    if config.wheel_acceleration_limit is not None and wb.base_input == "wheels":
        limits.append(WheelAccelerationLimit(wb, config.wheel_acceleration_limit))
    if band is not None:
        limits.append(SafetyBandLimit(wb, band))
    return limits


class ResolvedRateController:
    """End-effector resolved-rate control of a `WholeBody`, one QP per step.

    The QP's cost is the sum of `tasks` and its constraints those of `limits` (lists built from the
    config, then `extra_tasks` / `extra_limits` appended; both lists may be edited between steps).
    """

    def __init__(
        self,
        wb: WholeBody,
        config: ControllerConfig = ControllerConfig(),
        band: SafetyBand | None = None,
        posture: npt.ArrayLike | None = None,
        extra_tasks: Sequence[Task] = (),
        extra_limits: Sequence[Limit] = (),
    ) -> None:
        self.wb = wb
        self.config = config
        self.band = band
        p = posture if posture is not None else config.posture
        self.u_prev = np.zeros(wb.n_u)
        self._posture = None if p is None else np.asarray(p, dtype=float)
        self.tasks: list[Task] = default_tasks(wb, config, self._posture) + list(extra_tasks)
        self.limits: list[Limit] = default_limits(wb, config, band) + list(extra_limits)
        primary = direct_solver(config)
        self.solvers = SolverChoice(primary, config.fallback_solver, config.solver_tolerance)
        self.workspace = QPWorkspace(wb.n_u)
        self._no_twist = np.zeros(6)

    @property
    def posture(self) -> np.ndarray | None:
        """Arm posture of the posture task (None until the first step if not given)."""
        return self._posture

    @posture.setter
    def posture(self, value: npt.ArrayLike | None) -> None:
        self._posture = None if value is None else np.asarray(value, dtype=float)
        for task in self.tasks:
            if isinstance(task, PostureTask):
                task.posture = self._posture
        self.workspace.reset()  # the posture task's Hessian is constant only while its posture is set

    def bounds(self, x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Return the input box (lb, ub) of the limits: position limits over dt, speed limits; contains 0."""
        return stack_box(self.limits, StepState(self.wb, self.wb.as_state(x), dt, u_prev=self.u_prev))

    def inequalities(
        self,
        x: np.ndarray,
        dt: float,
        band_center: npt.ArrayLike | None,
        band_center_velocity: npt.ArrayLike | None,
        relax: bool = False,
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Return (G, h) of G u <= h: wheel limits of a twist input, and the safety band (§VI).

        With `relax`, the band's right-hand sides are raised to >= 0 so that u = 0 is feasible.
        """
        s = StepState(
            self.wb,
            self.wb.as_state(x),
            dt,
            u_prev=self.u_prev,
            band_center=band_center,
            band_center_velocity=band_center_velocity,
        )
        G, h = stack_inequalities(self.limits, s, relax)
        return (None, None) if G is None or h is None else (G.copy(), h.copy())  # (both or neither are None)

    def step(
        self,
        x: npt.ArrayLike,
        T_des: pin.SE3,
        v_des: npt.ArrayLike | None,
        dt: float,
        band_center: npt.ArrayLike | None = None,
        band_center_velocity: npt.ArrayLike | None = None,
        base_target: npt.ArrayLike | None = None,
        base_target_velocity: npt.ArrayLike | None = None,
    ) -> StepResult:
        """Return the input tracking pose `T_des` with feed-forward twist `v_des` (world-aligned) over dt.

        `base_target` (x, y, theta) and its world rates `base_target_velocity` feed the optional base
        regularisation (active when `config.base_weight > 0`).
        """
        if not dt > 0:
            raise WholeBodyError(f"dt must be positive, got {dt}")
        wb, cfg = self.wb, self.config
        x = wb.as_state(x)
        v_des = self._no_twist if v_des is None else np.asarray(v_des, dtype=float)
        if v_des.shape != (6,):
            raise WholeBodyError(f"feed-forward twist v_des must have 6 entries, got shape {v_des.shape}")
        if self._posture is None:
            self.posture = x[3:].copy()
        T, J = wb.ee_and_jacobian(x)
        e = pose_error(T, T_des)
        v_ref, position_error, orientation_error = reference_twist(
            e, cfg.gain, v_des, cfg.max_linear_speed, cfg.max_angular_speed
        )
        s = StepState(
            wb, x, dt, T, J, v_ref, self.u_prev, band_center, band_center_velocity, base_target, base_target_velocity
        )
        sol = solve_step(self.tasks, self.limits, s, self.solvers, self.workspace)
        u = sol.u
        self.u_prev = u.copy()
        residual = residual_norm(J, u, v_ref)
        return StepResult(
            u=u,
            position_error=position_error,
            orientation_error=orientation_error,
            residual=residual,
            saturated=bool(residual > cfg.residual_tolerance),
            solver_ok=sol.solver_ok,
            fallback_used=sol.fallback_used,
            jacobian=J,
            singular_threshold=cfg.singular_threshold,
        )
