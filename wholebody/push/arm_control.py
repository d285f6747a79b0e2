"""Arm laws of the MuJoCo plant: how an arm applies the allocated hand wrench through its own dynamics.

Two kinds of arm, two laws (the plant picks one per robot, see `mujoco_plant.ARM_MODES`):

- **Torque-controlled arm** (the iiwa, joint torque control): each physics step

  ``tau = arm_torque + J^T K_f (w - w_f) + N^T (K (q_plan(t) - q) + D (v_plan - v))``, clipped to the effort limits,

  where ``arm_torque`` is the controller's command (the arm's bias forces from Pinocchio's RNEA at the
  measured state + ``J^T w`` of the allocated hand wrench ``w``), ``q_plan(t)`` the plan interpolated
  over the period (``arm_position - arm_velocity (t_end - t)``) and ``N^T = I - J^T Jbar^T`` the
  dynamically consistent null-space projector (``Jbar = M^-1 J^T (J M^-1 J^T)^-1``; ``J`` the hand's
  6 x n_arm Jacobian, ``M`` the arm's joint-space inertia, both refreshed once per control period).
  The joint impedance holds the posture (the elbow of a 7-joint arm) without pushing on the hand: the
  hand's wrench stays the commanded ``J^T w`` while the hand moves with the handle it holds. ``w_f`` is the
  wrist F/T reading mapped to the grasp (world-aligned), read every physics step and low-passed (10 ms): the
  force loop (``K_f = 2``) divides the arm's own task-space inertia that the cart feels (19 kg along x at the
  push posture, as much as the cart) by ``1 + K_f``; ``K_f >= 4`` rings with the filter and the grasp.

- **Velocity-controlled arm** (the WMRA's, joint velocity servos): once per control period, an
  admittance around the servos,

  ``qdot_set = J^+ (J qdot + A (w - w_meas + K_i int(w - w_meas))) + N (arm_velocity + k_q (arm_position - q))``,

  with ``A = diag(a_f I3, a_n I3)`` (m/s per N, rad/s per N m), ``J^+`` a damped pseudo-inverse, ``N =
  I - J^+ J`` and ``w_meas`` the F/T reading mapped to the hand (world-aligned at the grasp). The hand
  holds the handle, so in task space the setpoint is the hand's measured motion plus the admittance:
  the servo's velocity error there is ``A (...)`` and its force the push (a damping force controller
  whose loop gain is ``A`` times the servo's task-space damping); where the hand pushes less than
  allocated it moves into the handle, and the other way round. The drives' integral action holds the
  arm's static load (the plant feeds each joint its bias forces).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TorqueArmGains:
    """Joint impedance of the torque law, acting in the hand's null space."""

    #: joint stiffness (N m/rad) and damping (N m s/rad)
    stiffness: float = 200.0
    damping: float = 20.0
    #: "command": the feed-forward is the command's ``arm_torque`` (the controller's RNEA + J^T w);
    #: "bias": the arm's bias forces (gravity, Coriolis) at the measured state, every physics step, + J^T w
    #: of the command's ``hand_wrench``; "dynamics": the arm's inverse dynamics at the measured state with
    #: the base's measured acceleration and the plan's arm acceleration, every physics step, + J^T w
    feedforward: str = "command"
    #: True: the impedance acts in the hand's null space only; False: on every joint (it then also damps the
    #: hand's motion relative to the plan)
    null_space: bool = True
    #: Cartesian stiffness (N m/rad) and damping (N m s/rad) holding the hand's roll and pitch (about the world's
    #: horizontal axes) at the command's ``hand_target``: the grip keeps the cart upright against the roll
    #: moment of a lateral push at the handle's height; 0 = off. It leaves the planar push alone.
    tilt_stiffness: float = 0.0
    tilt_damping: float = 0.0
    #: Cartesian stiffness (N/m) and damping (N s/m) pulling the hand's position toward the command's
    #: ``hand_target`` (its velocity: the target's change over the period); 0 = off (pure wrench control)
    cartesian_stiffness: float = 0.0
    cartesian_damping: float = 0.0
    #: F/T force feedback: ``J^T K_f (w - w_f)`` with ``w_f`` the wrist F/T reading (at the grasp, world-aligned)
    #: low-passed with time constant ``force_filter_tau`` (s), read every physics step; it divides the arm's own
    #: task-space inertia and friction felt by the cart by ``1 + K_f``; 0 = off (open-loop J^T w)
    force_feedback: float = 2.0
    force_filter_tau: float = 0.01


@dataclass(frozen=True)
class AdmittanceGains:
    """Admittance of the velocity law: hand velocity per unit wrench error, integral gain, posture gain."""

    #: m/s per N and rad/s per N m
    force_gain: float = 0.001
    torque_gain: float = 0.005
    #: 1/s: integral of the wrench error (removes the steady error under a constant push)
    integral_gain: float = 2.0
    #: 1/s: null-space pull toward the planned joint positions
    posture_gain: float = 2.0
    #: largest admittance correction of the hand velocity (m/s; rad/s for the rotation)
    max_speed: float = 0.3
    #: damping of the pseudo-inverse (m^2)
    pinv_damping: float = 1e-4


def null_space_projector_T(J: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Return N^T = I - J^T Jbar^T, the dynamically consistent null-space projector of joint torques."""
    Minv = np.linalg.inv(M)
    lam = np.linalg.inv(J @ Minv @ J.T + 1e-9 * np.eye(J.shape[0]))
    Jbar = Minv @ J.T @ lam
    return np.eye(M.shape[0]) - J.T @ Jbar.T


def damped_pinv(J: np.ndarray, damping: float) -> np.ndarray:
    """Return J^T (J J^T + damping I)^-1."""
    return J.T @ np.linalg.inv(J @ J.T + damping * np.eye(J.shape[0]))


class TorqueArmLaw:
    """The torque law of one arm (see the module docstring); `begin` once per period, `torque` each physics step."""

    def __init__(
        self, effort_limit: np.ndarray, gains: TorqueArmGains = TorqueArmGains(), physics_dt: float = 0.002
    ) -> None:
        self.limit = np.asarray(effort_limit, dtype=float)
        self.gains = gains
        self._alpha = physics_dt / (gains.force_filter_tau + physics_dt)
        self._w_d = np.zeros(6)
        self._w_f: np.ndarray | None = None
        self._ff = np.zeros(self.limit.size)
        self._NT = np.eye(self.limit.size)
        self._q_end = np.zeros(self.limit.size)
        self._v = np.zeros(self.limit.size)
        self._t_end = 0.0
        self.peak_ratio = 0.0
        self.saturated_steps = 0
        self.a_plan = np.zeros(self.limit.size)
        self._started = False

    def begin(
        self,
        hand_wrench: np.ndarray,
        arm_torque: np.ndarray,
        arm_position: np.ndarray,
        arm_velocity: np.ndarray,
        J: np.ndarray,
        M: np.ndarray,
        t_end: float,
        dt: float,
    ) -> None:
        """Take the period's command, the hand Jacobian (6, n), the arm inertia (n, n); the period of `dt` ends at `t_end`."""
        v_new = np.asarray(arm_velocity, dtype=float)
        self.a_plan = (v_new - self._v) / dt if self._started else np.zeros_like(v_new)
        self._started = True
        self._w_d = np.asarray(hand_wrench, dtype=float)
        if self.gains.feedforward in ("bias", "dynamics"):
            self._ff = J.T @ np.asarray(hand_wrench, dtype=float)
        else:
            self._ff = np.asarray(arm_torque, dtype=float)
        self._q_end = np.asarray(arm_position, dtype=float)
        self._v = v_new
        self._NT = null_space_projector_T(J, M) if self.gains.null_space else np.eye(M.shape[0])
        self._J = J
        self._Jr = J[3:]
        self._Jt = J[:3]
        self._t_end = t_end

    def torque(
        self,
        t: float,
        q: np.ndarray,
        v: np.ndarray,
        bias: np.ndarray,
        tilt: tuple[np.ndarray, np.ndarray] | None = None,
        hand: tuple[np.ndarray, np.ndarray] | None = None,
        wrench_measured: np.ndarray | None = None,
    ) -> np.ndarray:
        """Return the joint torques at time `t` and state (q, v), within limits.

        `hand`: (target position - hand position, target velocity - hand velocity), world frame, for the
        Cartesian impedance (None: off).

        `bias`: the arm's bias forces there; `tilt`: (rotation error hand -> target, hand angular velocity), world
        frame, for the roll/pitch hold (None: off); `wrench_measured`: the F/T reading at the grasp, world-aligned,
        for the force feedback (None: off).
        """
        g = self.gains
        q_plan = self._q_end - self._v * (self._t_end - t)
        ff = self._ff if g.feedforward == "command" else self._ff + bias
        tau = ff + self._NT @ (g.stiffness * (q_plan - q) + g.damping * (self._v - v))
        if hand is not None:
            p_err, v_err = hand
            tau = tau + self._Jt.T @ (g.cartesian_stiffness * p_err + g.cartesian_damping * v_err)
        if wrench_measured is not None and g.force_feedback > 0.0:
            w = np.asarray(wrench_measured, dtype=float)
            self._w_f = w.copy() if self._w_f is None else self._w_f + self._alpha * (w - self._w_f)
            tau = tau + self._J.T @ (g.force_feedback * (self._w_d - self._w_f))
        if tilt is not None and (g.tilt_stiffness > 0.0 or g.tilt_damping > 0.0):
            err, omega = tilt
            n = g.tilt_stiffness * err - g.tilt_damping * omega
            n[2] = 0.0  # roll and pitch only: the yaw torque is the allocation's
            tau = tau + self._Jr.T @ n
        ratio = float(np.max(np.abs(tau) / self.limit))
        self.peak_ratio = max(self.peak_ratio, ratio)
        if ratio > 1.0:
            self.saturated_steps += 1
            tau = np.clip(tau, -self.limit, self.limit)
        return tau


class AdmittanceArmLaw:
    """The admittance law of one velocity-controlled arm (see the module docstring), once per control period."""

    def __init__(self, n_arm: int, gains: AdmittanceGains = AdmittanceGains()) -> None:
        self.gains = gains
        self._integral = np.zeros(6)
        self.n = n_arm

    def velocity(
        self,
        arm_velocity: np.ndarray,
        arm_position: np.ndarray,
        q: np.ndarray,
        v: np.ndarray,
        J: np.ndarray,
        wrench: np.ndarray,
        wrench_measured: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """Return the joint-velocity setpoints for one period (wrenches world-aligned at the grasp, hand on cart)."""
        g = self.gains
        err = np.asarray(wrench, dtype=float) - np.asarray(wrench_measured, dtype=float)
        self._integral += err * dt
        gain = np.r_[np.full(3, g.force_gain), np.full(3, g.torque_gain)]
        twist = gain * (err + g.integral_gain * self._integral)
        for part in (slice(0, 3), slice(3, 6)):
            norm = float(np.linalg.norm(twist[part]))
            if norm > g.max_speed:
                twist[part] *= g.max_speed / norm
        Jp = damped_pinv(J, g.pinv_damping)
        N = np.eye(self.n) - Jp @ J
        plan = np.asarray(arm_velocity, dtype=float) + g.posture_gain * (np.asarray(arm_position) - q)
        # the hand moves with the handle it holds: in task space the servo follows the measured motion plus the
        # admittance (its velocity error is then the push), in the null space the plan
        return Jp @ (J @ np.asarray(v, dtype=float) + twist) + N @ plan
