"""Constraints (`Limit`s) of the resolved-rate QP: joint positions and speeds, wheel speeds and accelerations,
and the safety band (paper §VI).

Boxes that the robot's state could leave (position limits over dt) are widened to contain u = 0, so
the QP stays feasible; the safety band is `relaxable` (see `wholebody.motion.qp.solve_step`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from wholebody.errors import WholeBodyError
from wholebody.motion.kernels import intersect_position_box
from wholebody.motion.kinematics import WholeBody
from wholebody.motion.qp import Limit, StepState


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


class JointPositionLimit(Limit):
    """lower <= q + dt q_dot <= upper on the arm joints, widened to contain q_dot = 0."""

    def __init__(self, wb: WholeBody, margin: float = 0.0) -> None:
        self._bounds = np.stack([wb.arm_lower + margin, wb.arm_upper - margin])  # rows: lower, upper
        self.lower, self.upper = self._bounds[0], self._bounds[1]  # views: edit in place
        self._n_arm = wb.n_arm
        self._lb, self._ub = np.full(wb.n_u, -np.inf), np.full(wb.n_u, np.inf)  # reused by each call

    def box(self, s: StepState) -> tuple[np.ndarray, np.ndarray]:
        self._lb.fill(-np.inf)
        self._ub.fill(np.inf)
        self.intersect_box(s, self._lb, self._ub)
        return self._lb, self._ub

    def intersect_box(self, s: StepState, lb: np.ndarray, ub: np.ndarray) -> None:
        intersect_position_box(self.lower, self.upper, s.x, 3, s.dt, lb, ub)


class JointVelocityLimit(Limit):
    """|q_dot| <= the arm's velocity limits."""

    constant_box = True

    def __init__(self, wb: WholeBody) -> None:
        self._ub = np.full(wb.n_u, np.inf)
        self._ub[: wb.n_arm] = wb.arm_velocity_limit
        self._lb = -self._ub

    def box(self, s: StepState) -> tuple[np.ndarray, np.ndarray]:
        return self._lb, self._ub


class WheelVelocityLimit(Limit):
    """|wheel rates| <= the wheels' velocity limits.

    A box on wheel-rate inputs; for a body-twist input the inequalities |W t| <= limit (W: twist ->
    wheel rates), and after the solve the twist is scaled down so that they hold exactly.
    """

    constant_box = True
    constant_inequality = True

    def __init__(self, wb: WholeBody) -> None:
        self.limit = wb.wheel_velocity_limit
        self._n_arm = wb.n_arm
        self._twist = wb.base_input == "twist"
        if self._twist:
            W = wb.base.twist_to_wheels()
            Z = np.zeros((W.shape[0], wb.n_arm))
            self._G = np.vstack([np.hstack([Z, W]), np.hstack([Z, -W])])
            self._h = np.r_[self.limit, self.limit]
            self._W = W
        else:
            self._ub = np.full(wb.n_u, np.inf)
            self._ub[wb.n_arm :] = self.limit
            self._lb = -self._ub

    def box(self, s: StepState) -> tuple[np.ndarray, np.ndarray] | None:
        return None if self._twist else (self._lb, self._ub)

    def inequality(self, s: StepState, relax: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
        return (self._G, self._h) if self._twist else None

    @property
    def enforces(self) -> bool:
        return self._twist

    @property
    def has_inequality(self) -> bool:
        return self._twist

    def enforce(self, u: np.ndarray, s: StepState) -> None:
        if self._twist:
            ratio = (np.abs(self._W.dot(u[self._n_arm :])) / self.limit).max()
            if ratio > 1.0:
                u[self._n_arm :] /= ratio


class WheelAccelerationLimit(Limit):
    """|wheel rates - previous wheel rates| <= acceleration dt (wheel-rate inputs; contains the previous rates)."""

    def __init__(self, wb: WholeBody, acceleration: float) -> None:
        if not acceleration > 0:
            raise WholeBodyError(f"wheel acceleration limit must be positive, got {acceleration}")
        self.acceleration = acceleration
        self._n_arm = wb.n_arm
        self._lb, self._ub = np.full(wb.n_u, -np.inf), np.full(wb.n_u, np.inf)  # reused by each call

    def box(self, s: StepState) -> tuple[np.ndarray, np.ndarray]:
        if s.u_prev is None:
            raise WholeBodyError("the wheel acceleration limit needs the previous input (StepState.u_prev)")
        prev, step = s.u_prev[self._n_arm :], self.acceleration * s.dt
        np.subtract(prev, step, out=self._lb[self._n_arm :])
        np.add(prev, step, out=self._ub[self._n_arm :])
        return self._lb, self._ub


class SafetyBandLimit(Limit):
    """The look-ahead point P of the base stays in the band's polygon (paper §VI); relaxable.

    n . (P + dt Pdot - c - dt cdot) <= n . (P - c) + gain (R_in - n . (P - c)): P approaches the sides
    geometrically. Relaxed, the right-hand sides are raised to >= 0 so that u = 0 is feasible.
    """

    relaxable = True

    def __init__(self, wb: WholeBody, band: SafetyBand) -> None:
        self.band = band
        self.lookahead = band.lookahead_for(wb.base.holonomic)
        self._normals = band.normals()
        self._inner = band.inner_radius(self.lookahead)
        self._n_arm, self._n_u = wb.n_arm, wb.n_u

    def inequality(self, s: StepState, relax: bool = False) -> tuple[np.ndarray, np.ndarray]:
        c = np.zeros(2) if s.band_center is None else np.asarray(s.band_center, dtype=float)
        cdot = np.zeros(2) if s.band_center_velocity is None else np.asarray(s.band_center_velocity, dtype=float)
        ell, N = self.lookahead, self._normals
        c_th, s_th = s.cos_sin
        p = s.x[:2] + ell * np.array([c_th, s_th])  # look-ahead point P
        # velocity of P: paper eq. (12) with (L2, L3) = (ell, 0), chained with the base input map
        M = np.array([[c_th, -s_th, -ell * s_th], [s_th, c_th, ell * c_th]]).dot(s.wb.twist_map)
        G = np.zeros((N.shape[0], self._n_u))
        G[:, self._n_arm :] = N.dot(M)
        h = self.band.gain * (self._inner - N.dot(p - c)) / s.dt + N.dot(cdot)
        return G, (np.maximum(h, 0.0) if relax else h)


class JointTorqueLimit(Limit):
    """|tau| <= fraction x effort limit on the arm joints, with the joint torques the step's input asks for:

    tau = (M_a / dt + dh_a/dv) (S u - v_prev) + h_a(q, v_prev) + sum_k J_k^T w_k, linear in u (M_a: the arm rows
    of the joint-space inertia, S: input -> Pinocchio velocity, h: Pinocchio's nonlinear effects, linearised
    about the last input with `computeRNEADerivatives`, w_k: the wrench
    hand k applies, world-aligned at frame k, set in `wrenches` before each step). The acceleration a hand
    task asks for then never drives a joint past its URDF effort. Relaxable: when the QP has no solution
    with it (the bias alone beyond a limit, a position limit closing in), the step is solved without it.
    """

    relaxable = True
    #: share of a joint's effort its braking curve toward a position limit counts on (the rest: gravity, the hand)
    BRAKING_SHARE = 0.5

    def __init__(self, wb: WholeBody, fraction: float = 1.0, margin: float = 0.0) -> None:
        if not 0.0 < fraction <= 1.0:
            raise WholeBodyError(f"torque limit fraction must be in (0, 1], got {fraction}")
        self.wb, self.limit = wb, fraction * wb.arm_effort_limit
        #: joints with an effort limit (a URDF without one gives 0 or inf: that joint is not bounded)
        self.bounded = np.isfinite(self.limit) & (self.limit > 0)
        self.data = wb.model.createData()
        self.lower, self.upper = wb.arm_lower + margin, wb.arm_upper - margin
        self._lb, self._ub = np.full(wb.n_u, -np.inf), np.full(wb.n_u, np.inf)
        #: (frame id, wrench [f, n] world-aligned at the frame) of every hand for the coming step
        self.wrenches: list[tuple[int, np.ndarray]] = []
        #: indices of the mass matrix's strict lower triangle
        self._lower = np.tril_indices(wb.model.nv, -1)

    def box(self, s: StepState) -> tuple[np.ndarray, np.ndarray]:
        """Return each arm joint's speed toward its position limits (shrunk by `margin`) from which it still stops
        there decelerating at BRAKING_SHARE x effort / inertia per period (a discrete braking curve): so that a
        position limit never asks for a stop the torque limit cannot give."""
        wb, n = self.wb, self.wb.n_arm
        M = pin.crba(wb.model, self.data, wb.to_pinocchio_q(s.x))
        rows = wb.arm_idx_v
        a = self.BRAKING_SHARE * np.where(self.bounded, self.limit, 1.0) / np.maximum(M[rows, rows], 1e-9)
        step = a * s.dt * s.dt
        q = s.x[3 : 3 + n]
        for d, out, sign in ((self.upper - q, self._ub, 1.0), (q - self.lower, self._lb, -1.0)):
            k = np.sqrt(0.25 + 2.0 * np.maximum(d, 0.0) / step) - 0.5  # periods of braking the distance allows
            out[:n] = np.where(self.bounded, sign * k * a * s.dt, sign * np.inf)
        return self._lb, self._ub

    def inequality(self, s: StepState, relax: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
        if relax or not self.bounded.any():
            return None
        wb, model, data = self.wb, self.wb.model, self.data
        q = wb.to_pinocchio_q(s.x)
        S = wb.input_map
        u_prev = np.zeros(wb.n_u) if s.u_prev is None else s.u_prev
        v_prev = S @ u_prev
        M = pin.crba(model, data, q).copy()  # its upper triangle: mirrored below
        low = self._lower
        M[low] = M.T[low]
        rows = wb.arm_idx_v[self.bounded]
        # velocity terms to first order about the last input: h(v) ~ h(v_prev) + dh/dv (v - v_prev)
        pin.computeRNEADerivatives(model, data, q, v_prev, np.zeros(model.nv))
        Ma = (M[rows] / s.dt + data.dtau_dv[rows]) @ S
        bias = pin.nonLinearEffects(model, data, q, v_prev)[rows] - Ma @ u_prev
        for fid, w in self.wrenches:
            J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
            bias = bias + J[:, rows].T @ w
        lim = self.limit[self.bounded]
        return np.vstack([Ma, -Ma]), np.concatenate((lim - bias, lim + bias))
