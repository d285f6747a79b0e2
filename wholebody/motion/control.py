"""Resolved-rate end-effector control as a QP per step (paper eq. 21 with limits, §VI safety band).

Each step solves, over the input ``u = [arm rates, base input]``::

    min  ||J u - (v_d + K e)||_W^2 + damping ||u||^2 + secondary(u)
         [+ base_weight ||M u_b - (vb_d + K_b e_b)||^2  when a base target is given]
    s.t. joint position limits (as rate bounds over dt), joint and wheel speed limits,
         optional safety band: the base origin stays inside a disc (inscribed polygon).

`u = 0` always satisfies the constraints (bounds are relaxed to contain 0), so the
QP is feasible; if the solver fails anyway the step returns zero motion and says so.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pinocchio as pin
import qpsolvers

from wholebody.errors import WholeBodyError
from wholebody.motion.kinematics import WholeBody


@dataclass(frozen=True)
class SafetyBand:
    """A disc the base origin must stay in (paper §VI), approximated by an inscribed polygon.

    The constrained point is a look-ahead point P at body offset (lookahead, 0): its
    velocity is fully actuated even on a differential drive (paper eq. 12 with L3 = 0),
    so the linearised band constraint is always feasible. P is kept in the disc of
    radius R - lookahead, hence the base origin (within `lookahead` of P) stays within R.

    Attributes:
        radius: disc radius R (m).
        n_sides: polygon sides; the half-planes are n_j . (P - c) <= (R - lookahead) cos(pi / n_sides).
        gain: fraction (0, 1] of the remaining distance to a side P may cover per step.
        lookahead: offset of P ahead of the base origin (m); None = R/4 for a nonholonomic base, 0 otherwise.
    """

    radius: float
    n_sides: int = 16
    gain: float = 0.5
    lookahead: float | None = None

    def __post_init__(self) -> None:
        if not (self.radius > 0 and np.isfinite(self.radius)):
            raise WholeBodyError(f"safety band radius must be a positive number of metres, got {self.radius}")
        if self.n_sides < 3 or not (0 < self.gain <= 1):
            raise WholeBodyError("safety band needs n_sides >= 3 and 0 < gain <= 1")
        if self.lookahead is not None and not (0 <= self.lookahead < self.radius):
            raise WholeBodyError("safety band lookahead must be in [0, radius)")

    def lookahead_for(self, holonomic: bool) -> float:
        """Return the look-ahead offset (m) used for a base."""
        if self.lookahead is not None:
            return float(self.lookahead)
        return 0.0 if holonomic else 0.25 * self.radius

    def normals(self) -> np.ndarray:
        """Return the (n_sides x 2) outward unit normals of the polygon's sides."""
        a = 2 * np.pi * np.arange(self.n_sides) / self.n_sides
        return np.column_stack([np.cos(a), np.sin(a)])

    def inner_radius(self, lookahead: float) -> float:
        """Return the inradius (R - lookahead) cos(pi / n_sides) of the look-ahead point's polygon (m)."""
        return (self.radius - lookahead) * np.cos(np.pi / self.n_sides)


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
        solver: a `qpsolvers` solver name.
        solver_tolerance: absolute tolerance passed to proxqp (its default 1e-5 perturbs the
            rates by ~1e-4 rad/s); other solvers use their defaults.
        fallback_solver: solver tried when `solver` returns nothing (proxqp can fail on degenerate
            active sets, e.g. a safety band pinning the base's forward speed to 0 from both sides), or None.
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
    solver: str = "proxqp"
    fallback_solver: str | None = "daqp"
    solver_tolerance: float = 1e-9
    base_weight: float = 0.0
    base_gain: float = 2.0
    base_lookahead: float = 0.0
    wheel_acceleration_limit: float | None = None

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


@dataclass(frozen=True)
class StepResult:
    """One control step: the input and what happened.

    Attributes:
        u: input [arm rates, base input] to apply for dt (finite, within the limits).
        position_error, orientation_error: pose error before the step (m, rad).
        residual: ||J u - v_ref|| (task velocity not achieved).
        sigma_min: smallest singular value of the combined Jacobian.
        singular: sigma_min < threshold.
        saturated: residual > tolerance (limits or singularity prevented the commanded motion).
        solver_ok: False if every QP solver failed (then u = 0).
        fallback_used: True if the primary solver failed and the fallback solved the step.
    """

    u: np.ndarray
    position_error: float
    orientation_error: float
    residual: float
    sigma_min: float
    singular: bool
    saturated: bool
    solver_ok: bool
    fallback_used: bool = False


def pose_error(T: pin.SE3, T_des: pin.SE3) -> np.ndarray:
    """Return the world-aligned error [p_d - p, log3(R_d R^T)] (6,)."""
    return np.r_[T_des.translation - T.translation, pin.log3(T_des.rotation @ T.rotation.T)]


def _clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v if n <= limit else v * (limit / n)


class ResolvedRateController:
    """End-effector resolved-rate control of a `WholeBody`, one QP per step."""

    def __init__(self, wb: WholeBody, config: ControllerConfig = ControllerConfig(),
                 band: SafetyBand | None = None, posture: Sequence[float] | None = None) -> None:
        self.wb = wb
        self.config = config
        self.band = band
        p = posture if posture is not None else config.posture
        self.u_prev = np.zeros(wb.n_u)
        self.posture = None if p is None else np.asarray(p, dtype=float)
        n = wb.n_u
        w = np.r_[np.full(3, config.position_weight), np.full(3, config.orientation_weight)]
        self._W = np.diag(w)
        self._reg = config.damping * np.eye(n)
        self._lower = wb.arm_lower + config.limit_margin
        self._upper = wb.arm_upper - config.limit_margin
        if self.band is not None:
            self._band_normals = self.band.normals()
        if wb.base_input == "twist":
            H = wb.base.twist_to_wheels()
            self._G_wheels = np.vstack([np.hstack([np.zeros((H.shape[0], wb.n_arm)), H]),
                                        np.hstack([np.zeros((H.shape[0], wb.n_arm)), -H])])
            self._h_wheels = np.r_[wb.wheel_velocity_limit, wb.wheel_velocity_limit]

    def bounds(self, x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Return the input box (lb, ub): position limits over dt, speed limits; always contains 0."""
        wb = self.wb
        q = x[3:]
        vmax = wb.arm_velocity_limit
        lb = np.empty(wb.n_u)
        ub = np.empty(wb.n_u)
        lb[:wb.n_arm] = np.maximum(-vmax, (self._lower - q) / dt)
        ub[:wb.n_arm] = np.minimum(vmax, (self._upper - q) / dt)
        if wb.base_input == "wheels":
            lb[wb.n_arm:] = -wb.wheel_velocity_limit
            ub[wb.n_arm:] = wb.wheel_velocity_limit
        else:
            lb[wb.n_arm:] = -np.inf
            ub[wb.n_arm:] = np.inf
        lb, ub = np.minimum(lb, 0.0), np.maximum(ub, 0.0)
        a = self.config.wheel_acceleration_limit
        if a is not None and wb.base_input == "wheels":  # contains the previous wheel rates, hence feasible
            w = slice(wb.n_arm, wb.n_u)
            lb[w] = np.maximum(lb[w], self.u_prev[w] - a * dt)
            ub[w] = np.minimum(ub[w], self.u_prev[w] + a * dt)
        return lb, ub

    def inequalities(self, x: np.ndarray, dt: float, band_center: Sequence[float] | None,
                     band_center_velocity: Sequence[float] | None,
                     relax: bool = False) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Return (G, h) of G u <= h: wheel limits of a twist input, and the safety band (§VI).

        With `relax`, the band's right-hand sides are raised to >= 0 so that u = 0 is feasible.
        """
        wb = self.wb
        Gs, hs = [], []
        if wb.base_input == "twist":
            Gs.append(self._G_wheels)
            hs.append(self._h_wheels)
        if self.band is not None:
            c = np.zeros(2) if band_center is None else np.asarray(band_center, dtype=float)
            cdot = np.zeros(2) if band_center_velocity is None else np.asarray(band_center_velocity, dtype=float)
            th = x[2]
            ell = self.band.lookahead_for(wb.base.holonomic)
            c_th, s_th = np.cos(th), np.sin(th)
            p = x[:2] + ell * np.array([c_th, s_th])  # look-ahead point P
            # velocity of P: paper eq. (12) with (L2, L3) = (ell, 0), chained with the base input map
            M = np.array([[c_th, -s_th, -ell * s_th], [s_th, c_th, ell * c_th]]) @ wb._wheel_map
            N = self._band_normals
            G = np.zeros((N.shape[0], wb.n_u))
            G[:, wb.n_arm:] = N @ M
            # n.(P + dt Pdot - c - dt cdot) <= n.(P - c) + gain (R_in - n.(P - c)): approach sides geometrically
            slack = self.band.inner_radius(ell) - N @ (p - c)
            h = self.band.gain * slack / dt + N @ cdot
            Gs.append(G)
            hs.append(np.maximum(h, 0.0) if relax else h)
        if not Gs:
            return None, None
        return np.vstack(Gs), np.concatenate(hs)

    def _secondary(self, x: np.ndarray) -> np.ndarray:
        """Return the linear cost term (n_u,) of the secondary objective (to be minimised)."""
        wb, cfg = self.wb, self.config
        g = np.zeros(wb.n_u)
        if cfg.secondary == "posture" and self.posture is not None:
            g[:wb.n_arm] = -cfg.secondary_weight * cfg.posture_gain * (self.posture - x[3:])
        elif cfg.secondary == "manipulability":
            g[:wb.n_arm] = -cfg.secondary_weight * manipulability_gradient(wb, x)
        return g

    def _base_term(self, x: np.ndarray, base_target: Sequence[float],
                   base_target_velocity: Sequence[float] | None) -> tuple[np.ndarray, np.ndarray]:
        """Return (Hessian block, linear term) over the base input of base_weight ||M u_b - t*||^2.

        t* is the body twist of world rates vb_d + base_gain (pose_d - pose) (heading error wrapped).
        """
        cfg = self.config
        pose_d = np.asarray(base_target, dtype=float)
        rates = np.zeros(3) if base_target_velocity is None else np.asarray(base_target_velocity, dtype=float)
        th = x[2]
        ell = cfg.base_lookahead
        if ell > 0:  # look-ahead point P = base + ell (cos th, sin th) towards the target's P*
            c, s = np.cos(th), np.sin(th)
            cd, sd = np.cos(pose_d[2]), np.sin(pose_d[2])
            p = x[:2] + ell * np.array([c, s])
            p_d = pose_d[:2] + ell * np.array([cd, sd])
            pdot_d = rates[:2] + ell * rates[2] * np.array([-sd, cd])
            ref = pdot_d + cfg.base_gain * (p_d - p)
            M = np.array([[c, -s, -ell * s], [s, c, ell * c]]) @ self.wb._wheel_map  # paper 2 eq. (12), (ell, 0)
            return cfg.base_weight * M.T @ M, -cfg.base_weight * M.T @ ref
        e = np.array([pose_d[0] - x[0], pose_d[1] - x[1], (pose_d[2] - th + np.pi) % (2 * np.pi) - np.pi])
        w = rates + cfg.base_gain * e
        c, s = np.cos(th), np.sin(th)
        twist = np.array([c * w[0] + s * w[1], -s * w[0] + c * w[1], w[2]])  # world rates -> body twist
        M = self.wb._wheel_map
        return cfg.base_weight * M.T @ M, -cfg.base_weight * M.T @ twist

    def step(self, x: Sequence[float], T_des: pin.SE3, v_des: Sequence[float] | None, dt: float,
             band_center: Sequence[float] | None = None,
             band_center_velocity: Sequence[float] | None = None,
             base_target: Sequence[float] | None = None,
             base_target_velocity: Sequence[float] | None = None) -> StepResult:
        """Return the input tracking pose `T_des` with feed-forward twist `v_des` (world-aligned) over dt.

        `base_target` (x, y, theta) and its world rates `base_target_velocity` feed the optional base
        regularisation (active when `config.base_weight > 0`).
        """
        if not dt > 0:
            raise WholeBodyError(f"dt must be positive, got {dt}")
        wb, cfg = self.wb, self.config
        x = np.asarray(x, dtype=float)
        if self.posture is None:
            self.posture = x[3:].copy()
        T, J = wb.ee_and_jacobian(x)
        e = pose_error(T, T_des)
        v_ff = np.zeros(6) if v_des is None else np.asarray(v_des, dtype=float)
        v_ref = v_ff + cfg.gain * e
        v_ref = np.r_[_clip_norm(v_ref[:3], cfg.max_linear_speed), _clip_norm(v_ref[3:], cfg.max_angular_speed)]
        JW = J.T @ self._W
        P = JW @ J + self._reg
        if cfg.secondary == "posture" and self.posture is not None:
            P[:wb.n_arm, :wb.n_arm] += cfg.secondary_weight * np.eye(wb.n_arm)
        qv = -JW @ v_ref + self._secondary(x)
        if base_target is not None and cfg.base_weight > 0:
            Pb, qb = self._base_term(x, base_target, base_target_velocity)
            P[wb.n_arm:, wb.n_arm:] += Pb
            qv[wb.n_arm:] += qb
        lb, ub = self.bounds(x, dt)
        solver_ok, fallback_used = True, False
        u = None
        for relax in ((False, True) if self.band is not None else (False,)):
            G, h = self.inequalities(x, dt, band_center, band_center_velocity, relax=relax)
            u = _solve(P, qv, G, h, lb, ub, cfg.solver, cfg.solver_tolerance)
            if u is None and cfg.fallback_solver is not None:
                u = _solve(P, qv, G, h, lb, ub, cfg.fallback_solver, cfg.solver_tolerance)
                fallback_used = u is not None
            if u is not None:
                break
        if u is None:
            u = np.zeros(wb.n_u)
            solver_ok = False
        u = np.clip(u, lb, ub)  # solver tolerance: make the box exact
        if wb.base_input == "twist":  # scale the base twist so the wheel speed limits hold exactly
            ratio = np.max(np.abs(wb.base.twist_to_wheels() @ u[wb.n_arm:]) / wb.wheel_velocity_limit)
            if ratio > 1.0:
                u[wb.n_arm:] /= ratio
        self.u_prev = u.copy()
        s = np.linalg.svd(J, compute_uv=False)
        residual = float(np.linalg.norm(J @ u - v_ref))
        return StepResult(u=u, position_error=float(np.linalg.norm(e[:3])), orientation_error=float(np.linalg.norm(e[3:])),
                          residual=residual, sigma_min=float(s[-1]), singular=bool(s[-1] < cfg.singular_threshold),
                          saturated=bool(residual > cfg.residual_tolerance), solver_ok=solver_ok,
                          fallback_used=fallback_used)


def _solve(P, q, G, h, lb, ub, solver: str, tolerance: float) -> np.ndarray | None:
    """Return the QP solution, or None if the solver fails or returns non-finite values."""
    options = {"eps_abs": tolerance, "eps_rel": 0.0} if solver == "proxqp" else {}
    try:
        u = qpsolvers.solve_qp(P, q, G, h, lb=lb, ub=ub, solver=solver, **options)
    except Exception:  # noqa: BLE001 - any solver failure is reported as None
        return None
    if u is None or not np.all(np.isfinite(u)):
        return None
    return u


def manipulability(wb: WholeBody, x: Sequence[float]) -> float:
    """Return the arm's manipulability sqrt(det(J_arm J_arm^T)) at x."""
    J = wb.combined_jacobian(x)[:, :wb.n_arm]
    return float(np.sqrt(max(np.linalg.det(J @ J.T), 0.0)))


def manipulability_gradient(wb: WholeBody, x: Sequence[float], eps: float = 1e-6) -> np.ndarray:
    """Return d manipulability / d q_arm by central differences (n_arm,)."""
    x = np.asarray(x, dtype=float)
    g = np.zeros(wb.n_arm)
    for i in range(wb.n_arm):
        dx = np.zeros_like(x)
        dx[3 + i] = eps
        g[i] = (manipulability(wb, x + dx) - manipulability(wb, x - dx)) / (2 * eps)
    return g
