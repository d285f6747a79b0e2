"""Gains of the velocity-servo arm law (`admittance_law.AdmittanceArmLaw`) from the arm's own model.

A velocity-servoed arm pushes through its servos: joint ``i`` applies ``k_v,i (qdot_set,i - qdot_i)`` on top of
the drive's hold of its static load, within its effort limit ``tau_max,i``. One servo damping for every arm
(the WMRA's 80 N m s/rad) fits an arm whose joints carry 10-60 N m; on TIAGo's wrist (3 N m on ``arm_5_joint``,
6.6 N m on 6 and 7) a velocity error of 0.04 rad/s already saturates it, and a hand held by the handle sees
velocity errors of that size every control period. Here each joint's damping is its drive's torque-speed line:

    ``k_v,i = tau_max,i / qdot_max,i``  (capped at the plant's servo damping),

the servo reaches its effort limit at a velocity error of the joint's own speed limit (URDF ``effort`` and
``velocity``). The admittance then closes its loop through these servos with the gain set in every direction
(`admittance_law.AdmittanceGains.loop_gain`): ``A = L J K_v^-1 J^T``, so that the hand's force per unit wrench error
``A (J K_v^-1 J^T)^-1 = L`` (the servos' task-space damping is ``(J K_v^-1 J^T)^-1``) and the servo torques of the
correction are ``L J^T`` of it, the scale of the push itself. With one diagonal ``A`` for all arms the loop gain
is the arm's task-space damping times ``A``: 0.05-4.2 over the WMRA's directions, 0.1-3.4 over TIAGo's.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

#: the admittance's loop gain (`admittance_law.AdmittanceGains.loop_gain`): the hand's force correction per unit of
#: wrench error per control period, well inside the one-period delay's stability bound of 2. The F/T's noise bounds
#: it: the period-mean of its samples (1.3 N per axis) enters the push ``L`` times. Measured with the integral
#: (`admittance_law.DEFAULT_INTEGRAL_GAIN`): 0.1 / 0.2 / 0.3 (``L K_i`` 5 / 2 / 1.5 /s) put the WMRA's wrench error on
#: Traj. 2 at 14.9 / 15.9 / 16.3 % of the hand force, but 0.1 loses TIAGo's Traj. 1 at 15.3 s (0.2: 21.2 mm RMS;
#: `cartpush push --plant mujoco --robot wmra|tiago.toml --trajectory 1|2 --json`)
LOOP_GAIN = 0.2


def servo_damping(effort_limit: np.ndarray, velocity_limit: np.ndarray, kv_max: float = np.inf) -> np.ndarray:
    """Return each joint's servo damping ``k_v,i = tau_max,i / qdot_max,i`` (N m s/rad), at most `kv_max`.

    The servo's torque at a velocity error of the joint's speed limit is its effort limit (a drive's torque-speed
    line). A joint without a finite positive effort or speed limit gets `kv_max`.
    """
    tau = np.asarray(effort_limit, dtype=float)
    vel = np.asarray(velocity_limit, dtype=float)
    ok = np.isfinite(tau) & np.isfinite(vel) & (tau > 0.0) & (vel > 0.0)
    kv = np.full(tau.shape, float(kv_max))
    kv[ok] = np.minimum(tau[ok] / vel[ok], kv_max)
    if not np.all(np.isfinite(kv)):
        raise ValueError("a joint without effort and speed limits needs a finite kv_max")
    return kv


def loop_admittance(J: np.ndarray, kv: np.ndarray, loop_gain: float) -> np.ndarray:
    """Return the admittance ``A = L J K_v^-1 J^T`` (6 x 6) whose loop gain through servos of damping `kv` is `L`.

    The servos' task-space damping is ``D = (J K_v^-1 J^T)^-1`` (a hand velocity error ``dv`` makes the force
    ``D dv``); the admittance's twist ``A e`` then makes ``D A e = L e``.
    """
    return loop_gain * (J / np.asarray(kv, dtype=float)) @ J.T


def loop_gains(J: np.ndarray, kv: np.ndarray, A: np.ndarray) -> np.ndarray:
    """Return the admittance loop's gains: the eigenvalues of ``D A`` (``D = (J K_v^-1 J^T)^-1``), ascending."""
    D = np.linalg.inv((J / np.asarray(kv, dtype=float)) @ J.T)
    return np.sort(np.linalg.eigvals(D @ A).real)


@dataclass(frozen=True)
class ArmServoTuning:
    """One arm's velocity-servo gains, derived from its limits (`arm_tuning`)."""

    #: the servos' damping per joint (N m s/rad)
    kv: np.ndarray
    #: the admittance's loop gain (`loop_admittance`)
    loop_gain: float


def arm_tuning(
    effort_limit: np.ndarray, velocity_limit: np.ndarray, kv_max: float, loop_gain: float | None = None
) -> ArmServoTuning:
    """Return one arm's servo damping per joint (`servo_damping`, at most `kv_max`) and the admittance's loop gain
    (`loop_gain`, default `LOOP_GAIN`)."""
    kv = servo_damping(effort_limit, velocity_limit, kv_max)
    return ArmServoTuning(kv, LOOP_GAIN if loop_gain is None else float(loop_gain))


def set_servo_damping(model: mujoco.MjModel, actuators: np.ndarray, kv: np.ndarray) -> None:
    """Set the damping of MuJoCo velocity actuators `actuators` to `kv` (``gainprm[0] = kv``, ``biasprm[2] =
    -kv``: force ``kv (ctrl - qdot)``)."""
    for a, k in zip(np.asarray(actuators, dtype=int), np.asarray(kv, dtype=float)):
        model.actuator_gainprm[a, 0] = k
        model.actuator_biasprm[a, 2] = -k
