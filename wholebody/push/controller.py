"""The push controller: what a real robot gives in, what a real robot takes out (cart paper §II–III).

One control period, :meth:`PushController.step` with a :class:`~wholebody.push.plant.Measurement`:

1. the F/T readings of the last period, mapped to the cart through each robot's measured kinematics
   and the grasp map (paper eq. 23–24), and the motion-capture pose update the estimator
   (``ParameterEstimator.step``: the paper's EKF eq. 8–20, or any other);
2. the cart controller gives the desired cart wrench Gamma_MM (eq. 26) from the estimate;
3. contact points on the handle (fixed, or re-planned from the estimated model) and the wrench
   allocation QP (eq. 25) give each hand's wrench;
4. each robot's whole-body QP follows its grasp point on the (estimated) handle; the arm torques
   are ``rnea(q, v, a) + J^T w`` (Pinocchio).

It holds no simulated truth: everything it reads comes through the measurement, so the same
object drives the kinematic plant, the MuJoCo plant or real robots.
"""

from __future__ import annotations

import math
from contextlib import nullcontext
from dataclasses import dataclass, replace
from functools import lru_cache
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from cart import model as cart_model
from cart.params import CartParams
from cart.trajectories import CartTrajectory
from wholebody.contacts.allocation import AllocationResult, WrenchAllocator
from wholebody.contacts.support import CartLoad
from wholebody.errors import WholeBodyError
from wholebody.push.config import CartController, ParameterEstimator, PushConfig
from wholebody.push.plant import Measurement, RobotCommand
from wholebody.push.robot import MobileManipulator, base_target, ft_to_cart_gamma, grasp_target, handle_point
from wholebody.push.scheduler import ContactScheduler
from wholebody.motion.tasks import BaseTask, PostureTask
from wholebody.push.base_plan import BasePlan
from wholebody.push.reference_clock import (
    ReferenceClock,
    TimeScaling,
    admissible_rate,
    deficit,
    footprint_params,
    needs_look_ahead,
    path_braking,
)
from wholebody.push.slip_hold import SlipHold, lateral_demand
from wholebody.push.tip_support import cart_load, finite_or_zero


#: allocations per period with the tip-over bound when the allocation saturates (`PushController._allocate`)
TIP_LOAD_PASSES = 3

#: the largest share of the estimated mass and of the footprint's half-size the tip-over bound's margin takes off
#: (`PushController._cart_load`)
TIP_MARGIN_SHARE = 0.25

#: time constant (s) of the filter between the cart estimate and the pose the hands hold (`PushController._grasp_pose`)
GRASP_FILTER_TAU = 0.1


@dataclass(frozen=True)
class ControlDecision:
    """What the controller decided in one period (its estimate, the cart wrench, contacts, hand wrenches, torques)."""

    t: float
    params_hat: CartParams
    #: (6,) estimated cart state (x, y, theta, xdot, ydot, thetadot)
    x_hat: np.ndarray
    #: (2,) 1-sigma of the mass (kg) and of the CoM (m); NaN when the estimator gives no covariance
    param_std: np.ndarray
    #: (3,) desired Gamma_MM (eq. 26)
    gamma_desired: np.ndarray
    #: (3,) Gamma_MM measured by the F/T sensors over the last period (eq. 23-24)
    gamma_measured: np.ndarray
    #: (n_arms,) contact points y on the handle (m, in {b})
    contact_y: np.ndarray
    #: (n_arms, 6) hand wrenches in {a} (eq. 25)
    wrenches_ee: np.ndarray
    #: True when the allocation could not produce the desired wrench
    saturated: bool
    #: (n_arms, n_arm_joints) arm torques and their J^T w part (N m)
    arm_torque: np.ndarray
    push_torque: np.ndarray
    #: (n_arms, 3) base body twists commanded
    base_twist: np.ndarray
    #: (n_arms, n_wheels) wheel rates commanded (rad/s)
    wheel_rates: np.ndarray
    #: (n_arms,) hand target position error of the robot's measured state (m)
    grasp_error: np.ndarray
    #: the limit that kept the allocation from the desired wrench (None when not saturated)
    binding: str | None = None
    #: the reference time s the controller followed this period and its rate ds/dt (`ReferenceClock`; s = t, 1
    #: without time scaling)
    reference_time: float = 0.0
    reference_rate: float = 1.0


def param_std(estimator: ParameterEstimator) -> np.ndarray:
    """Return the estimator's 1-sigma of (mass [kg], CoM [m, the norm over x and y], CoM x [m], CoM y [m]); NaN when
    it gives no covariance."""
    std = getattr(estimator, "params_std", None)
    if std is None:
        return np.full(4, np.nan)
    s = std()
    cx, cy = (float(v) for v in s["com"])
    return np.array([s["mass"], float(np.hypot(cx, cy)), cx, cy])


class PushController:
    """Closed-loop push controller of one or two mobile manipulators holding the cart's handle.

    ``robots`` are the controller's models of the robots (Pinocchio model, whole-body QP tracker,
    grasp geometry); their states are overwritten from each measurement. ``clock``: the reference's time scaling
    (`wholebody.push.reference_clock`), shared with the cart controller's `ScaledReference`; None: s = t.
    """

    def __init__(
        self,
        config: PushConfig,
        cart_controller: CartController,
        estimator: ParameterEstimator,
        scheduler: ContactScheduler,
        robots: Sequence[MobileManipulator],
        clock: ReferenceClock | None = None,
    ) -> None:
        if sum(mm.n_hands for mm in robots) != config.n_arms:
            raise WholeBodyError(
                f"{len(robots)} robots holding {sum(mm.n_hands for mm in robots)} hands given for {config.n_arms} arms"
            )
        self.config = config
        self.cart_controller = cart_controller
        self.estimator = estimator
        self.scheduler = scheduler
        self.robots = list(robots)
        self.clock = clock
        self.trajectory = config.make_trajectory()
        self.geometry = config.cart_geometry()
        #: the cart's floor contacts the allocation keeps loaded (None: no tip-over bound)
        self.support = config.support_polygon() if config.tip_on() else None
        hands = config.hand_limits([a for mm in self.robots for a in mm.arms])  # each arm's own grip
        limits = list(hands) if self.support is None else [replace(h, planar=False) for h in hands]
        self._limits = limits
        self.allocator = WrenchAllocator(
            [handle_point(v, self.geometry) for v in scheduler.y], limits, only_motion_directions=True
        )
        #: whether the cart slides sideways (`wholebody.push.slip_hold`): then the hands hold its lateral motion too
        self.slip = SlipHold()
        self._t_prev: float | None = None
        self._q_grasp: np.ndarray | None = None
        self._t_grasp: float | None = None
        self.last: ControlDecision | None = None
        #: per robot: its base plan (`wholebody.push.base_plan`) when `PushConfig.base_plan` is set, else None
        edges = np.cumsum([0] + [mm.n_hands for mm in self.robots])
        self.base_plans = [self._base_plan(mm, float(scheduler.y[a])) for mm, a in zip(self.robots, edges[:-1])]
        #: per robot: its hands' rows of the allocation (`_by_robot`): a slice for several hands, an index for one
        self._cuts = [slice(a, b) if b - a > 1 else a for a, b in zip(edges[:-1].tolist(), edges[1:].tolist())]
        #: per robot: its QP's own (posture weight, posture), restored outside a plan's windows
        self._own_terms: dict[int, tuple[float, np.ndarray | None]] = {}
        #: the clock's settings and their copy with the momentum horizon (`_look_ahead_settings`)
        self._ahead: tuple[TimeScaling, TimeScaling] | None = None

    def _base_plan(self, mm: MobileManipulator, contact_y: float) -> BasePlan | None:
        """Return robot `mm`'s base plan over the desired motion (None: not asked for, several hands, not holonomic),
        and guard its elbow (`BasePlanSettings.elbow_guard`)."""
        settings = self.config.plan_settings()
        if settings is None or mm.n_hands != 1 or not mm.wb.base.holonomic:
            return None
        from wholebody.push.base_plan import guard_elbow, plan_base

        plan = plan_base(mm, self.config.make_trajectory(), float(contact_y), settings)
        if settings.elbow_guard is not None:
            guard_elbow(mm, settings.elbow_guard)
        return plan

    def step(self, m: Measurement) -> list[RobotCommand]:
        """Return one command per robot for the period starting at ``m.t`` (see the module docstring)."""
        if len(m.robots) != len(self.robots):
            raise WholeBodyError(f"measurement has {len(m.robots)} robots, the controller {len(self.robots)}")
        for mm, r in zip(self.robots, m.robots):
            mm.x = np.concatenate((r.base_pose, r.q_arm))
        gamma_meas = self._measured_gamma(m)
        if self._t_prev is not None:  # the wrench of the last period and the pose at its end (eq. 8-20)
            self.estimator.step(gamma_meas, m.t - self._t_prev, m.z)
        self._t_prev = m.t
        dt = self.config.dt
        params_hat = self.estimator.params()
        x_hat = np.array(self.estimator.x[:6], dtype=float)
        q_hat, qd_hat = x_hat[0:3], x_hat[3:6]
        s, rate, gamma_d = self._demand(m.t, q_hat, qd_hat, params_hat)
        gamma_d = self._hold_slide(m.t, s, q_hat, qd_hat, params_hat, gamma_d)
        ys, ydots = self.scheduler.update(s, params_hat, dt)
        alloc = self._allocate(q_hat, qd_hat, gamma_d, params_hat, ys)
        saturated = alloc.residual > 1e-6 * max(1.0, float(np.abs(gamma_d).max()))  # eq. (25)
        self._advance_clock(s, q_hat, cart_model.generalized_to_body(q_hat, gamma_d), alloc.gamma_achieved, params_hat)
        q_grasp = self._grasp_pose(q_hat, qd_hat, m.t)
        gamma_a = _body_to_generalized(q_hat, alloc.gamma_achieved)
        qdd = np.asarray(cart_model.forward_dynamics(q_hat, qd_hat, gamma_a, params_hat), dtype=float)
        commands, per_robot = zip(
            *(
                self._robot_command(mm, q_grasp, qd_hat, y, yd, w, s, plan, qdd, rate)
                for mm, y, yd, w, plan in zip(
                    self.robots, *self._by_robot(ys, ydots, alloc.wrenches_ee), self.base_plans
                )
            )
        )
        parts = [p for ps in per_robot for p in ps]  # one (torque, J^T w, grasp error) per hand
        self.last = ControlDecision(
            t=m.t,
            params_hat=params_hat,
            x_hat=x_hat,
            param_std=param_std(self.estimator),
            gamma_desired=gamma_d,
            gamma_measured=gamma_meas,
            contact_y=np.array(ys, dtype=float),
            wrenches_ee=np.array(alloc.wrenches_ee, dtype=float),
            saturated=bool(saturated),
            arm_torque=hand_rows([p[0] for p in parts]),
            push_torque=hand_rows([p[1] for p in parts]),
            base_twist=np.array([c.base_twist for c in commands]),
            wheel_rates=np.array([c.wheel_rates for c in commands]),
            grasp_error=np.array([p[2] for p in parts]),
            binding=alloc.binding if saturated else None,
            reference_time=s,
            reference_rate=rate,
        )
        return list(commands)

    def _hold_slide(
        self, t: float, s: float, q: np.ndarray, qd: np.ndarray, params: CartParams, gamma: np.ndarray
    ) -> np.ndarray:
        """Return the desired wrench `gamma` ({s}) with its lateral part in {b} the one a sliding cart's motion asks
        of the hands (`slip_hold.lateral_demand` at the reference read on the clock) once the cart has been seen
        sliding (`SlipHold`), and from then on allocate all three rows: the allocation then no longer makes the yaw
        torque with a sideways push that a missing axle does not take. Unchanged while the cart does not slide."""
        if not self.slip.update(t, q, qd, self.config.dt):
            return gamma
        if len(self.allocator.rows) < 3:
            points = [handle_point(v, self.geometry) for v in self.scheduler.y]
            self.allocator = WrenchAllocator(points, self._limits, only_motion_directions=False)
        q_d, qd_d, qdd_d = self.trajectory.sample(s)
        r, rd = (1.0, 0.0) if self.clock is None else (self.clock.rate, self.clock.rate_dot)
        ref = (q_d, qd_d * r, qdd_d * (r * r) + qd_d * rd)
        gamma_b = cart_model.generalized_to_body(q, gamma)
        gamma_b[1] = lateral_demand(q, qd, ref, params, self.slip.settings)
        return _body_to_generalized(q, gamma_b)

    def _advance_clock(
        self, s: float, q: np.ndarray, gamma_b: np.ndarray, achieved: np.ndarray, params: CartParams
    ) -> None:
        """Set the reference's rate for the next period from this one's allocation (`ReferenceClock.advance`): the
        share of the demand it left out, the desired path speed at s, the hands' force over the estimated mass, and
        the estimated cart's distance from the reference (`reference_clock.error_rate_cap`)."""
        if self.clock is None:
            return
        self._look_ahead(s, params)
        self._plan_cap(s, params)
        rows = self.allocator.rows
        q_d, qd, qdd = self.trajectory.sample(s)
        share = deficit(np.asarray(gamma_b)[rows], np.asarray(achieved)[rows], path_braking(qd, qdd))
        path_speed = float(np.hypot(*qd[:2]))
        error = float(np.hypot(q_d[0] - q[0], q_d[1] - q[1]))
        self.clock.advance(share, self.config.dt, path_speed, self._accel_bound(params), error)

    def _plan_cap(self, s: float, params: CartParams) -> None:
        """Cap the clock's rate where a base plan's window meets the wheel limits only slower (`BasePlan.rates`): at
        reference time s, the largest rate from which the reference slows to each such window's rate by its start
        at the look-ahead's path deceleration (`TimeScaling.plan_share` of the brake bound, `BasePlan.rate_cap`)."""
        assert self.clock is not None
        plans = [p for p in self.base_plans if p is not None and any(r < 1.0 for r in p.rates)]
        if plans:
            decel = self.clock.settings.plan_share * self._rate_decel(s, params)
            self.clock.cap = min(p.rate_cap(s, decel) for p in plans)

    def _accel_bound(self, params: CartParams) -> float:
        """Return the acceleration (m/s^2) the hands' total force bound gives the estimated mass; inf without a mass."""
        force = self.config.n_arms * self.config.arm_limits.max_force
        return force / params.m if params.m > 0 else float("inf")

    def _look_ahead(self, s: float, params: CartParams) -> None:
        """Every `TimeScaling.check_period` of reference time: the largest rate from which the reference can slow in
        time to one whose feed-forward the arms can give over the horizon (`reference_clock.admissible_rate`), with
        the allocation's limits as they are now, the tip-over bound under each sample's motion (with the allocation's
        margin, `_cart_load`) and the estimate's
        inertia at least its mass spread over the wheels (`reference_clock.footprint_params`). The allocator's own
        tip rows are put back afterwards."""
        clock = self.clock
        settings = self._look_ahead_settings(s, params)
        if clock is None or settings is None or s - clock.checked_at < settings.check_period:
            return
        clock.checked_at = s
        if self.support is not None:
            params = footprint_params(params, np.asarray(self.support.points, dtype=float))

        def achievable(row: np.ndarray) -> bool:
            if self.support is not None:
                state = np.array([row[3], 0.0, row[4]])
                self.allocator.set_tip_bound(self.support, self._cart_load(np.zeros(3), state, row[:3], params))
            return self.allocator.optimum(row[:3]) is not None

        decel = settings.plan_share * self._rate_decel(s, params, settings)
        with self.allocator.tip_bound_kept() if self.support is not None else nullcontext():
            clock.admissible = admissible_rate(self.trajectory, s, settings, params, achievable, decel)

    def _look_ahead_settings(self, s: float, params: CartParams) -> TimeScaling | None:
        """Return the clock's settings when it looks ahead at reference time s: its own with a horizon, else with
        `TimeScaling.momentum_horizon` while the estimated cart's stopping distance at the path's top speed over
        that horizon is over `TimeScaling.stop_distance` (`reference_clock.needs_look_ahead`); None: no look-ahead."""
        if self.clock is None:
            return None
        settings = self.clock.settings
        if settings.horizon > 0:
            return settings
        if settings.momentum_horizon <= 0:
            return None
        if self._ahead is None or self._ahead[0] is not settings:
            self._ahead = (settings, replace(settings, horizon=settings.momentum_horizon))
        ahead = self._ahead[1]
        speed = max_path_speed(self.trajectory, s, horizon_times(ahead.horizon, ahead.horizon_samples))
        force = self.config.n_arms * self.config.arm_limits.max_force
        if needs_look_ahead(float(params.m), speed, force, settings):
            return ahead
        self.clock.admissible = 1.0
        return None

    def _rate_decel(self, s: float, params: CartParams, settings: TimeScaling | None = None) -> float:
        """Return the path deceleration (1/s) the clock's brake bound allows at reference time s: `brake_share` of
        the hands' total force over the estimated mass, over the desired path speed (the largest over the horizon
        when the path is at rest at s); inf when the path does not move."""
        assert self.clock is not None
        settings = self.clock.settings if settings is None else settings
        speed = max_path_speed(self.trajectory, s, horizon_times(settings.horizon, settings.horizon_samples))
        accel = self._accel_bound(params)
        if speed <= 1e-9 or not math.isfinite(accel):
            return float("inf")
        return settings.brake_share * accel / speed

    def _demand(self, t: float, q: np.ndarray, qd: np.ndarray, params: CartParams) -> tuple[float, float, np.ndarray]:
        """Return the reference time s at time t, its rate (`ReferenceClock`; t and 1 without one) and the desired
        wrench Gamma_d of the cart controller (eq. 26) at s, bounded (`bounded_demand`)."""
        s, rate = (t, 1.0) if self.clock is None else (self.clock.time(t), self.clock.rate)
        gamma = np.asarray(self.cart_controller.gamma(s, q, qd, params), dtype=float)  # eq. (26)
        return s, rate, bounded_demand(gamma, self.config.n_arms * self.config.arm_limits.max_force)

    def _allocate(
        self, q: np.ndarray, qd: np.ndarray, gamma: np.ndarray, params: CartParams, ys: np.ndarray
    ) -> AllocationResult:
        """Return the allocation (eq. 25) of the desired wrench `gamma` ({s}) at the contacts `ys` under the arms'
        limits (their joint torques at the arms' current configuration) and, with the tip-over bound, every wheel
        loaded under the cart's inertia.

        The inertia the bound counts is the cart's acceleration under the wrench the hands will give: the desired
        one when the allocation gives it; when it saturates, the acceleration of a wrench the arms cannot give
        is not the cart's (a turn asked past the arms' torque asks a yaw acceleration whose CoM swing tips the cart
        on paper, and the bound then forbids the very sideways push that would turn it): the load is then taken
        under the achieved wrench, up to `TIP_LOAD_PASSES` times while the achieved wrench still moves.
        """
        self.allocator.set_points([handle_point(v, self.geometry) for v in ys])
        if self.config.torque_margin is not None:  # |J^T w + g| <= tau_max at each arm's current configuration
            self.allocator.set_torque_limits(
                [c for mm in self.robots for c in mm.torque_constraints(q)],
                margin=self.config.torque_margin,
                stack=self.support is None,  # else set_tip_bound below takes them in
            )
        gamma_b = cart_model.generalized_to_body(q, gamma)
        if self.support is None:
            return self.allocator.solve(gamma_b, raise_on_infeasible=False)
        load_gamma = gamma
        for _ in range(TIP_LOAD_PASSES):
            self.allocator.set_tip_bound(self.support, self._cart_load(q, qd, load_gamma, params))
            alloc = self.allocator.solve(gamma_b, raise_on_infeasible=False)
            if alloc.residual <= 1e-6 * max(1.0, float(np.abs(gamma).max())):
                return alloc
            given = _body_to_generalized(q, alloc.gamma_achieved)
            if np.allclose(given, load_gamma, rtol=1e-3, atol=1e-3):
                return alloc
            load_gamma = given
        return alloc

    def _cart_load(self, q: np.ndarray, qd: np.ndarray, gamma: np.ndarray, params: CartParams) -> CartLoad:
        """Return the cart's load on its wheels under the desired wrench (`tip_support.cart_load`), with the
        estimator's 1-sigma when `PushConfig.tip_std_factor` asks for a margin.

        The margin guards against the estimate's error; a misfitting estimator scales its 1-sigma up by its residual
        ratio (`cart.online_estimator.OnlineLSEstimator.params_std`: the hospital bed's 206 +- 116 kg, CoM y +-
        0.22 m on a 0.8 m track), and that margin forbade the sideways push that steers the cart (its hand pressed
        down at the 150 N bound and pushed sideways 30-60 N). So it takes off at most `TIP_MARGIN_SHARE` of the
        estimated mass and of the wheels' footprint's half-size along x and y."""
        factor = self.config.tip_std_factor
        std_of = getattr(self.estimator, "params_std", None)
        std = std_of() if std_of is not None and factor > 0.0 else None
        if std is not None and self.support is not None:
            pts = np.asarray(self.support.points, dtype=float)
            half = 0.5 * (pts.max(axis=0) - pts.min(axis=0))
            cap = TIP_MARGIN_SHARE / factor
            com = np.minimum(finite_or_zero(np.asarray(std["com"], dtype=float)), cap * half)
            std = dict(std, mass=min(float(std["mass"]), cap * float(params.m)), com=[float(v) for v in com])
        return cart_load(q, qd, gamma, params, std, factor)

    def _grasp_pose(self, q_hat: np.ndarray, qd_hat: np.ndarray, t: float) -> np.ndarray:
        """Return the cart pose the hands hold: the estimate, predicted with its velocity and corrected with
        time constant `GRASP_FILTER_TAU` (the hands follow the handle, not the motion capture's noise)."""
        if self._q_grasp is None or self._t_grasp is None:
            self._q_grasp, self._t_grasp = q_hat.copy(), t
            return self._q_grasp
        h = t - self._t_grasp
        pred = self._q_grasp + h * qd_hat
        err = q_hat - pred
        err[2] = (err[2] + np.pi) % (2.0 * np.pi) - np.pi
        self._q_grasp = pred + min(1.0, h / GRASP_FILTER_TAU) * err
        self._t_grasp = t
        return self._q_grasp

    def _follow_plan(self, mm: MobileManipulator, posture: np.ndarray | None) -> None:
        """Pull robot `mm`'s base to its place (the plan's inside a window, the rigid one outside) with
        `BasePlanSettings.base_weight` and `base_gain` all through the run, and its arm to the plan's `posture` with
        `posture_weight` inside a window (`posture` given); outside (None) the QP's own posture term is back.

        The base is held firmly everywhere because a held hand does not follow the QP's arm rates: the handle
        carries it. The QP's hand task (gain x the hand's pose error: the grasp's give under the push, the
        estimate's offset) and its posture term trade the base's motion against arm rates that a torque-controlled
        arm does not make; with the QP's own weak pull (`PUSH_CONTROLLER.base_weight`) the base then falls behind
        the cart at the rate of that trade and the arm stretches to its straight-elbow singularity (the 90 kg
        wheelchair on Traj. 1: 10 cm behind by 14 s, the elbow from 1.03 to 0.13 rad, lost)."""
        ctrl, settings = getattr(mm.tracker, "controller", None), self.config.plan_settings()
        tasks = getattr(ctrl, "tasks", ())
        pt = next((k for k in tasks if isinstance(k, PostureTask)), None)
        bt = next((k for k in tasks if isinstance(k, BaseTask)), None)
        if ctrl is None or settings is None or pt is None or bt is None:
            return
        own = self._own_terms.setdefault(id(mm), (pt.weight, pt.posture))
        bt.weight, bt.gain = settings.base_weight, settings.base_gain
        if posture is None:
            if pt.weight != own[0]:
                pt.weight = own[0]
                ctrl.posture = own[1]  # resets the QP's constant Hessian
            return
        if pt.weight != settings.posture_weight:
            pt.weight = settings.posture_weight
            ctrl.posture = posture
        pt.posture = posture

    def _measured_gamma(self, m: Measurement) -> np.ndarray:
        """Return Gamma_MM of the F/T readings, through each robot's measured F/T frame (eq. 23-24)."""
        gamma = np.zeros(3)
        for mm, r in zip(self.robots, m.robots):
            for ft_id, ft in zip(mm.ft_ids, np.reshape(r.ft, (-1, 6))):  # one reading per hand
                oMft = mm.wb.frame_placement(mm.x, ft_id)
                gamma += ft_to_cart_gamma(pin.Force(ft[:3], ft[3:]), oMft, m.cart_pose)
        return gamma

    def _by_robot(
        self, ys: np.ndarray, ydots: np.ndarray, wrenches: Sequence[np.ndarray] | np.ndarray
    ) -> tuple[list, list, list]:
        """Return the contacts, their rates and the hand wrenches per robot: a robot with one hand gets its
        own (y, ydot, wrench), one with several (one base, `MobileManipulator.n_hands` arms) arrays of them."""
        cut = self._cuts
        return [ys[c] for c in cut], [ydots[c] for c in cut], [np.asarray(wrenches)[c] for c in cut]

    def _robot_command(
        self,
        mm: MobileManipulator,
        q: np.ndarray,
        qd: np.ndarray,
        y: float | np.ndarray,
        ydot: float | np.ndarray,
        wrench_a: np.ndarray,
        t: float = 0.0,
        plan: BasePlan | None = None,
        qdd: np.ndarray | None = None,
        rate: float = 1.0,
    ) -> tuple[RobotCommand, list[tuple[np.ndarray, np.ndarray, float]]]:
        """Return (the command of one robot, per hand (arm torque, J^T w part, grasp error)) for one period.

        A robot with several hands (`_by_robot`: arrays of contacts and wrenches) gets one command: its arms'
        joints in turn, one hand wrench and one hand target per hand (rows). With a base `plan` the base follows
        the plan's place at reference time t, read at the reference's `rate`, and the arm its posture
        (`_follow_plan`). `qdd`: the cart's commanded acceleration (the allocated wrench through the estimated
        model); the hands' and the base's predicted accelerations are its rigid-body field at their points
        (`rigid_acceleration`), None: not predicted.
        """
        dt = self.config.dt
        ys, yds, ws = np.atleast_1d(y), np.atleast_1d(ydot), np.reshape(wrench_a, (-1, 6))
        targets = [grasp_target(q, qd, v, vd, R, self.geometry) for v, vd, R in zip(ys, yds, mm.grasp_rotations)]
        (target, vel), more = targets[0], {"more_targets": targets[1:]} if len(targets) > 1 else {}
        if plan is None:
            bpose, brates = base_target(q, qd, mm.base_offset_b)
        else:
            bpose, brates = plan.target(t, q, qd, mm.base_offset_b, rate)
            self._follow_plan(mm, plan.posture(t))
        R = _rot_z(q[2])
        w_world = [np.concatenate([R @ w[:3], R @ w[3:]]) for w in ws]
        mm.set_hand_wrenches(w_world)  # the QP keeps the joint torques within their limits
        u = mm.tracker.step(mm.x, target, vel, bpose, brates, dt, **more)
        taus, pushes, hands = mm.hand_torques(u, mm.u, dt, w_world)
        mm.u = u
        n = mm.wb.n_arm
        one = len(targets) == 1
        cmd = RobotCommand(
            arm_velocity=u[:n].copy(),
            arm_position=mm.x[3:] + dt * u[:n],
            arm_torque=np.concatenate(taus),
            base_twist=mm.body_twist(u),
            wheel_rates=mm.wb.wheel_rates(u),
            hand_wrench=w_world[0] if one else np.array(w_world),
            hand_target=target.homogeneous if one else np.array([T.homogeneous for T, _ in targets]),
            **({} if qdd is None else _predicted_accelerations(q, qd, qdd, [T for T, _ in targets], mm.x[:2])),
        )
        errors = [float(np.linalg.norm(P.translation - T.translation)) for P, (T, _) in zip(hands, targets)]
        return cmd, list(zip(taus, pushes, errors))


def hand_rows(rows: Sequence[np.ndarray]) -> np.ndarray:
    """Return per-hand joint vectors as the rows of one array, zero-padded where the arms' joint counts differ."""
    width = max(len(r) for r in rows)
    if all(len(r) == width for r in rows):
        return np.array([np.asarray(r, dtype=float) for r in rows])
    return np.array([np.pad(np.asarray(r, dtype=float), (0, width - len(r))) for r in rows])


#: A demand this many times what the hands can push (N, N m at 1 m) is scaled down to it before the allocation.
DEMAND_BOUND_FACTOR = 10.0


def bounded_demand(gamma: np.ndarray, hand_force: float) -> np.ndarray:
    """Return Gamma_d scaled down (direction kept) to `DEMAND_BOUND_FACTOR` x the hands' total force `hand_force`
    (torque in N m at a 1 m arm), and zero when it is not finite: after a lost cart or a diverged estimate the cart
    controller (eq. 26) can ask 1e13 N, which the allocation's solvers cannot take; any demand past the bound
    saturates the allocation either way."""
    if not np.isfinite(gamma).all():
        return np.zeros_like(gamma)
    bound = DEMAND_BOUND_FACTOR * hand_force
    peak = float(np.abs(gamma).max())
    return gamma * (bound / peak) if peak > bound else gamma


@lru_cache(maxsize=16)
def horizon_times(horizon: float, samples: int) -> tuple[float, ...]:
    """Return ``np.linspace(0, horizon, samples)`` as floats: the look-ahead's sample offsets (s)."""
    return tuple(np.linspace(0.0, horizon, samples).tolist())


def path_speed(trajectory: CartTrajectory, t: float) -> float:
    """Return the trajectory's desired path speed (m/s) at t: its ``path_speed`` when it has one, else the norm of
    its sampled planar velocity."""
    speed = getattr(trajectory, "path_speed", None)
    if speed is not None:
        return float(speed(t))
    return float(np.hypot(*trajectory.sample(t)[1][:2]))


def max_path_speed(trajectory: CartTrajectory, s: float, offsets: Sequence[float]) -> float:
    """Return the largest `path_speed` of the trajectory at the times s + each of `offsets` (s)."""
    speed = getattr(trajectory, "path_speed", None)
    if speed is None:
        return max(path_speed(trajectory, s + h) for h in offsets)
    return max([float(speed(s + h)) for h in offsets])


def _body_to_generalized(q: np.ndarray, gamma_b: np.ndarray) -> np.ndarray:
    """Return the generalized force (fx, fy in {s}, tau) of a body wrench (f_forward, f_lateral, tau) at pose q."""
    c, s = np.cos(q[2]), np.sin(q[2])
    return np.array([c * gamma_b[0] - s * gamma_b[1], s * gamma_b[0] + c * gamma_b[1], gamma_b[2]])


def rigid_acceleration(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Return the acceleration (6: linear at the world point `point` (x, y[, z]), then angular) of a point moving
    rigidly with the cart of pose `q`, velocity `qd` and acceleration `qdd` ({b} origin's (x, y, theta)):
    ``a = a_o + alpha x r + omega x (omega x r)``, planar (``r`` the point's offset from the {b} origin)."""
    rx, ry = float(point[0] - q[0]), float(point[1] - q[1])
    w, alpha = float(qd[2]), float(qdd[2])
    ax = float(qdd[0]) - alpha * ry - w * w * rx
    ay = float(qdd[1]) + alpha * rx - w * w * ry
    return np.array([ax, ay, 0.0, 0.0, 0.0, alpha])


def _predicted_accelerations(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, targets: Sequence[pin.SE3], base_xy: np.ndarray
) -> dict[str, np.ndarray]:
    """Return a command's ``hand_acceleration`` (one row per hand; (6,) for one) and ``base_acceleration``: the
    cart's commanded motion at the hands' targets and at the base (`rigid_acceleration`; the robot held at its
    place on the cart moves with it)."""
    hands = [rigid_acceleration(q, qd, qdd, T.translation) for T in targets]
    base = rigid_acceleration(q, qd, qdd, base_xy)
    return {"hand_acceleration": hands[0] if len(hands) == 1 else np.array(hands), "base_acceleration": base[[0, 1, 5]]}


def _rot_z(theta: float) -> np.ndarray:
    """Return the rotation about z by theta (3x3)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
