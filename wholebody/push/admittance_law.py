"""The admittance law of a velocity-controlled arm (the WMRA's, every profile robot's by default): the allocated hand
wrench applied through joint velocity servos, once per control period.

Each servo applies ``k_v (qdot_set - qdot)`` on top of the drive's hold of its static load (the plant feeds each joint
its bias forces), within the joint's effort limit. The hand holds the handle, so the arm's joint velocities are set
by the cart and the base; the servos' torque is what the setpoint adds to them. Per period:

``qdot_set = J^+ J (qdot + dqdot_plan) + K_v^-1 J^T s (w + u) + N (arm_velocity + k_q (arm_position - q))``,

- ``J^+ J (qdot + dqdot_plan)``: the hand's motion over the period, predicted as the measured joint velocity at the
  period's start plus the plan's change of it since the last period (``arm_velocity`` minus the last one: the
  cart's and the base's planned acceleration as the hand sees them); ``J^+`` a damped pseudo-inverse, ``N = I -
  J^+ J``;
- ``K_v^-1 J^T w``: the push fed forward through the servos (their torque ``J^T w`` at once);
- ``u = L (e + K_i int e)``, ``e = w_prev - w_meas``: a PI loop on the hand's wrench error, with ``w_meas`` the mean
  of the F/T samples over the last period (`AdmittanceArmLaw.sample`, one per physics step, world-aligned at the
  grasp) and ``w_prev`` the wrench allocated for that period (a jump of the allocation is the feed-forward's; the
  loop sees only what the hand did not deliver). Through ``K_v^-1 J^T`` the loop's hand force per unit error is ``L``
  in every direction (`loop_gain`; the servos' task-space damping ``(J K_v^-1 J^T)^-1`` times the admittance ``A = L
  J K_v^-1 J^T``, `admittance_tuning.loop_admittance`);
- ``s`` in [0, 1]: the loop's share that fits the effort limits with the push and the static load
  (`arm_control.torque_budget`); the integral holds while ``s < 1`` (anti-windup);
- ``K_v^-1 tau_a`` (not written above; off by default, `AdmittanceGains.hand_inertia`): the arm's own inertia under
  the command's predicted accelerations, ``tau_a = t + K a_base`` (`arm_control.hand_inertia_terms`: the hand's
  ``hand_acceleration``, the velocity-product term of the measured joint velocities, the base's planned
  acceleration), within the effort limits the push and the static load leave. Without it the push accelerates the
  arm's links with the cart, and the hand gives the cart that much less.

The loop's gain is bounded by the F/T's noise, not by its delay: the period-mean of ``n`` samples carries
``sigma / sqrt(n)`` per axis (1.3 N for 3 N at 500 Hz over 10 ms), passed into the push ``L`` times; the hand force's
own floor (the base's sway and the arm's inertia through the servos' damping, 300-2300 N s/m at the WMRA's hand) is
0.4-0.8 N per axis at rest. `admittance_tuning.LOOP_GAIN` and `DEFAULT_INTEGRAL_GAIN`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wholebody.push.admittance_tuning import LOOP_GAIN
from wholebody.push.arm_control import damped_pinv, torque_budget

#: 1/s: the integral of the wrench error, ``u = L (e + K_i int e)``: with ``L`` = `LOOP_GAIN` (0.2) the integral
#: alone closes the loop at ``L K_i`` = 2 /s. Measured (`cartpush push --plant mujoco --trajectory 1|2 --seed 0
#: --json`, ``L`` / ``K_i``; WMRA Traj. 1 and Traj. 2 wrench error, % of the hand force; TIAGo, the profile of
#: tests/robots/profile_files.py, Traj. 1 tracking): 0.1 / 50: 22.5 %, 14.9 %, TIAGo lost at 15.3 s; 0.3 / 5: 23.5 %,
#: 16.3 %; 0.2 / 10: 22.2 %, 15.9 %, TIAGo 21.2 mm. TIAGo's first 16 s: 12.2 mm (0.2 / 10) to 33.4 mm (0.1 / 10)
DEFAULT_INTEGRAL_GAIN = 10.0


@dataclass(frozen=True)
class AdmittanceGains:
    """Gains of the admittance law: its loop (proportional and integral), the posture, the servos' damping."""

    #: m/s per N and rad/s per N m: the diagonal admittance, used when ``loop_gain`` is None
    force_gain: float = 0.001
    torque_gain: float = 0.005
    #: 1/s: the integral of the wrench error, ``u = L (e + K_i int e)``
    integral_gain: float = DEFAULT_INTEGRAL_GAIN
    #: 1/s: null-space pull toward the planned joint positions
    posture_gain: float = 2.0
    #: largest correction of the hand velocity by the diagonal admittance (m/s; rad/s for the rotation)
    max_speed: float = 0.3
    #: damping of the pseudo-inverse (m^2)
    pinv_damping: float = 1e-4
    #: the joint velocity servos' damping k_v (N m s/rad): the push J^T w goes forward as their velocity offset
    #: J^T w / k_v; one per joint (a tuple) or one for all; None = the MuJoCo plant's own servos'
    #: (`ServoGains.arm_kv`), 0 = no feed-forward (the admittance alone makes the push)
    servo_kv: float | tuple[float, ...] | None = None
    #: the loop's gain L: the hand force per unit wrench error in every direction (``K_v^-1 J^T L``); None = the
    #: diagonal admittance (``force_gain``, ``torque_gain``; its loop gain then differs per direction)
    loop_gain: float | None = LOOP_GAIN
    #: True: the MuJoCo plant derives the servos' damping per joint from the arm's own limits (robots outside
    #: `mujoco_plant.TUNED_ADMITTANCE`, `admittance_tuning.arm_tuning`); False: ``servo_kv`` as given
    from_arm: bool = True
    #: True: the hand's predicted motion adds the plan's change of the joint velocities since the last period
    plan_acceleration: bool = True
    #: True: the servos add the arm's inertia under the command's predicted accelerations (`AdmittanceArmLaw.velocity`
    #: ``inertial``; the module docstring). Off: measured with the MuJoCo plant passing ``inertial`` (`cartpush push
    #: --plant mujoco --robot wmra --trajectory 2 --seed 0|1 --json`), the WMRA's wrench error falls from 10.6 / 10.3 %
    #: to 8.7 / 8.2 % of the hand force (the predicted inertia follows the measured one: correlation 0.98), but TIAGo
    #: (`--robot tiago.toml`, the profile of tests/robots/profile_files.py) loses Traj. 2 (19.4 mm RMS without): its
    #: base sways on slipping wheels, and the predicted inertia correlates 0.2-0.4 with the measured one
    hand_inertia: bool = False


class AdmittanceArmLaw:
    """The admittance law of one velocity-controlled arm (see the module docstring), once per control period."""

    def __init__(
        self, n_arm: int, gains: AdmittanceGains = AdmittanceGains(), effort_limit: np.ndarray | None = None
    ) -> None:
        self.gains = gains
        self.n = n_arm
        self.limit = None if effort_limit is None else np.asarray(effort_limit, dtype=float)
        self._integral = np.zeros(6)
        self._sum = np.zeros(6)
        self._count = 0
        self._w_prev: np.ndarray | None = None
        self._plan_prev: np.ndarray | None = None
        #: the loop's share that fit the effort limits in the last period (1: all of it)
        self.budget = 1.0

    def sample(self, wrench_measured: np.ndarray) -> None:
        """Take one F/T sample of the hand's wrench (world-aligned at the grasp); call once per physics step."""
        self._sum += np.asarray(wrench_measured, dtype=float)
        self._count += 1

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
        bias: np.ndarray | None = None,
        inertial: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """Return the joint-velocity setpoints for one period (wrenches world-aligned at the grasp, hand on cart).

        `wrench_measured` is used when no sample was taken since the last call (`sample`); `bias`: the arm's bias
        forces the drives hold (for the effort budget; None: zero); `inertial`: ``(t, K, a_base)``, the arm's inertial
        torque ``t + K a_base`` under the hand's predicted acceleration and the base's planned one
        (`arm_control.hand_inertia_terms`, as `TorqueArmLaw.begin` takes it), fed forward with
        `AdmittanceGains.hand_inertia` (None: none).
        """
        g = self.gains
        w = np.asarray(wrench, dtype=float)
        measured = self._sum / self._count if self._count else np.asarray(wrench_measured, dtype=float)
        self._sum, self._count = np.zeros(6), 0
        err = (w if self._w_prev is None else self._w_prev) - measured
        self._w_prev = w.copy()
        kv = np.broadcast_to(np.asarray(g.servo_kv if g.servo_kv else np.inf, dtype=float), (self.n,))
        Jp = damped_pinv(J, g.pinv_damping)
        plan = np.asarray(arm_velocity, dtype=float)
        motion = np.asarray(v, dtype=float) + self._plan_change(plan)
        posture = (np.eye(self.n) - Jp @ J) @ (plan + g.posture_gain * (np.asarray(arm_position) - q))
        if g.loop_gain is None or not g.servo_kv:
            return Jp @ (J @ motion + self._twist(err, dt)) + J.T @ w / kv + posture
        u = g.loop_gain * (err + g.integral_gain * self._integral)
        held = np.zeros(self.n) if bias is None else np.asarray(bias, dtype=float)
        inertia = self._inertia(inertial)
        inertia = inertia * self._budget(J, w, inertia, held)  # within the limits the push and the load leave
        self.budget = self._budget(J, w, J.T @ u, held + inertia)
        if self.budget >= 1.0:
            self._integral += err * dt
        return Jp @ (J @ motion) + (J.T @ (w + self.budget * u) + inertia) / kv + posture

    def _inertia(self, inertial: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> np.ndarray:
        """Return the arm's inertial torque ``t + K a_base`` to feed forward (zero when not wanted or not given)."""
        if not self.gains.hand_inertia or inertial is None:
            return np.zeros(self.n)
        t, K, a_base = (np.asarray(x, dtype=float) for x in inertial)
        if t.shape != (self.n,) or K.shape != (self.n, a_base.size):
            raise ValueError(
                f"inertial must be t ({self.n},), K ({self.n}, n_base), a_base (n_base,); got {t.shape}, {K.shape}"
            )
        return t + K @ a_base

    def _plan_change(self, plan: np.ndarray) -> np.ndarray:
        """Return the plan's joint velocity change since the last period (zero at first or when not wanted)."""
        change = np.zeros(self.n) if self._plan_prev is None else plan - self._plan_prev
        self._plan_prev = plan.copy()
        return change if self.gains.plan_acceleration else np.zeros(self.n)

    def _budget(self, J: np.ndarray, w: np.ndarray, extra: np.ndarray, held: np.ndarray) -> float:
        """Return the share ``s`` of the joint torque `extra` with ``|J^T w + held + s extra| <= limit`` (1 without
        limits)."""
        if self.limit is None:
            return 1.0
        return torque_budget(J.T @ w + held, extra, self.limit)

    def _twist(self, err: np.ndarray, dt: float) -> np.ndarray:
        """Return the diagonal admittance's twist ``A (e + K_i int e)``, each part within ``max_speed``."""
        g = self.gains
        self._integral += err * dt
        twist = np.r_[np.full(3, g.force_gain), np.full(3, g.torque_gain)] * (err + g.integral_gain * self._integral)
        for part in (slice(0, 3), slice(3, 6)):
            norm = float(np.linalg.norm(twist[part]))
            if norm > g.max_speed:
                twist[part] *= g.max_speed / norm
        return twist
