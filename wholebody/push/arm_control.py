"""Arm laws of the MuJoCo plant: how an arm applies the allocated hand wrench through its own dynamics.

Two kinds of arm, two laws (the plant picks one per robot, see `mujoco_plant.ARM_MODES`):

- **Torque-controlled arm** (the iiwa, joint torque control): each physics step

  ``tau = J^T w + b(q, v) + t_in + N^T LP(arm_torque - J^T w - b_0) + J^T K (e + K_i int e) + N^T (K_q (q_plan(t) - q)
  + D (v_plan - v))``, clipped to the effort limits (`TorqueArmGains.budget`: within them by priority instead,
  `TorqueArmLaw._prioritized`: the task part, then the hand's feedback as the closest wrench that fits,
  `fit_in_limits`, then the posture), with ``e = w - w_f``,

  where ``w`` is the allocated hand wrench, ``b`` the arm's bias forces at the step's state plus, while the hand
  holds, the hand-space part of the joints' modelled viscous damping (``J^T Jbar^T D v``, ``D`` the robot model's:
  `TorqueArmGains.passive_feedforward`), ``t_in`` the arm's own
  inertia under the hand's predicted acceleration (the handle's) and the base's measured one (`hand_inertia_terms`,
  `TorqueArmGains.hand_inertia`: the push then does not carry the arm), ``arm_torque`` the
  controller's command (Pinocchio's RNEA with the plan's velocities and accelerations + ``J^T w``), ``b_0`` the
  bias forces at the period's start and ``LP`` a low-pass over the periods (0.1 s; the plan term in the hand's
  null space only: `TorqueArmGains.plan_null_space`; see `TorqueArmGains.feedforward` for the other feed-forwards),
  ``q_plan(t)`` the plan interpolated over the period (``arm_position - arm_velocity (t_end - t)``) and ``N^T = I - J^T Jbar^T`` the dynamically consistent null-space
  projector (``Jbar = M^-1 J^T (J M^-1 J^T)^-1``; ``J`` the hand's 6 x n_arm Jacobian, ``M`` the arm's joint-space
  inertia, both refreshed once per control period). The joint impedance (its damping on the velocity at the physics
  step's end: `implicit_impedance`) holds the posture (the elbow of a 7-joint arm) without pushing on the hand: the
  hand's wrench stays the commanded ``J^T w`` while the hand moves with the handle it holds.

  The force loop (PI, ``K = 5`` on the force rows and 1 on the moment rows, ``K_i = 5 /s``) cancels what the
  arm's own dynamics take from the push: the cart feels the arm's task-space inertia (19 kg along x at the push posture, as much as the cart) whenever the
  hand accelerates relative to the base. Its measured wrench ``w_f`` is the hand's wrench at the grasp
  (world-aligned), low-passed (5 ms), fused from two sensors (a complementary filter): the arm's joint-side
  estimate ``w_j = -E tau_ext + F w_FT``, ``tau_ext = (M qdd)_arm + b - tau_joint`` (the external joint torque
  from the joint torques, accelerations and model, as a torque-sensing arm estimates it; free of the F/T's
  noise; ``tau_joint`` the law's own last command and the joints' modelled damping, plus the joint torque
  sensors' difference to both low-passed over 0.2 s: `TorqueArmGains.motor_torque_tau`), ``E = (J W J^T + R)^-1 J W``, ``F = (J W J^T + R)^-1 R`` the weighted least squares of the joint torques
  and the F/T's forces (``W = diag(1 / sigma_tau^2)``, a joint torque sensor's noise in proportion to its range,
  as much of it as the low-pass leaves;
  ``R`` the F/T's: where the joints see the hand, ``F`` is small; along a direction they do not see, a straight
  elbow's, the F/T's reading; `fused_estimator`), corrected by the wrist F/T at low frequency (6 s) (the F/T's accuracy:
  it removes the sensors' offsets, the model's slow errors, payload and friction): `TorqueArmGains.fusion_space`
  "joint" (default) takes the slow part of ``tau_ext + J^T w_FT``, each joint torque's error, off
  ``tau_ext`` (it stays removed as the arm moves and the base turns); "hand" adds the slow part of the F/T reading
  minus ``w_j``, kept in the frame of the arm's mount (`TorqueArmGains.fusion_frame`). Both slow parts can start
  from samples taken while the arm holds still before the push (`TorqueArmLaw.hold`, `TorqueArmLaw.tare`; the MuJoCo
  plant's settling, `MujocoPlantConfig.tare`), as a real arm zeroes its sensors before a task. Fed back directly,
  the F/T's white noise (3 N per sample at 500 Hz) would be pushed into the cart ``K_f`` times over. The loop's gain is bounded by its one-step
  delay and its measurement filter (`TorqueArmGains.force_feedback`). The integral stops while a torque is clipped or
  the budget trims the loop (anti-windup); the loop's wrench is applied only while the hand holds the handle
  (`TorqueArmLaw.torque`'s ``grasped``: a released hand has no wrench to control). `TorqueArmGains.reference_model`
  (on by default) compares ``w_f`` with the
  allocated wrench as the measurement sees it (one step late, low-passed) instead of ``w``.

- **Velocity-controlled arm** (the WMRA's, joint velocity servos): an admittance around the servos,
  `wholebody.push.admittance_law`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import daqp
import numpy as np

from cart.small_linalg import solve_small


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return ``np.linalg.solve(a, b)`` of a small system: LAPACK's gesv, the routine numpy calls, without numpy's
    per-call wrapping (2.3 of its 3.5 us), in numpy's (C) order: a matrix product rounds by its operands' layout."""
    return np.ascontiguousarray(solve_small(a, b))


def _inv(a: np.ndarray) -> np.ndarray:
    """Return ``np.linalg.inv(a)`` of a small matrix (gesv on the identity, as numpy; `_solve`)."""
    return _solve(a, np.eye(a.shape[0]))


@dataclass(frozen=True)
class TorqueArmGains:
    """Joint impedance of the torque law, acting in the hand's null space."""

    #: joint stiffness (N m/rad) and damping (N m s/rad)
    stiffness: float = 200.0
    damping: float = 20.0
    #: "smoothed" (default): J^T w + the arm's bias forces at the state of each physics step + the command's plan
    #: term (``arm_torque - J^T w - b_0``: the controller's RNEA with the plan's accelerations minus the bias forces
    #: at the period's start) low-passed with ``plan_filter_tau``; "refreshed": the command's ``arm_torque`` with
    #: its bias forces refreshed every step (+ b(q, v) - b_0); "command": the command's ``arm_torque`` held over
    #: the period; "bias": the bias forces + J^T w, no plan term; "dynamics": the arm's inverse dynamics at the
    #: state of each step with the base's measured acceleration and the plan's arm acceleration + J^T w.
    #: Measured (Traj. 1, examples/carts/wheelchair.xml, seeds 0/1/2): without a plan term the iiwa drifts to its
    #: straight-elbow singularity and the 90 kg wheelchair is lost at 25.9/25.7/11.5 s; "smoothed": tracked (4.8 mm
    #: RMS)/25.1/11.6 s. With the raw plan term ("refreshed") the plan's acceleration, a difference of 100 Hz
    #: velocity commands, puts its jitter into the push (default cart: wrench error 20 % against 12 %)
    feedforward: str = "smoothed"
    #: time constant (s) of the plan term's low-pass (mode "smoothed"): ten control periods
    plan_filter_tau: float = 0.1
    #: True: the impedance acts in the hand's null space only; False: on every joint (it then also damps the
    #: hand's motion relative to the plan)
    null_space: bool = True
    #: True: the joint impedance is taken at the end of the physics step, as the step will integrate it (the
    #: damping's velocity predicted from the arm's inertia: `implicit_impedance`); False: at its start. Held
    #: explicitly, a damping ``D`` on a motion whose inertia ``I`` is below ``D dt / 2`` flips sign every step and
    #: grows: near a straight iiwa elbow (joint 4 below about 0.2 rad) the null space gains the counter-rotation
    #: of joints 3 and 5 (a few hundredths of kg m^2, damped by ``D`` on both joints: unstable below ``2 D dt / 2``
    #: = 0.04 kg m^2), which drove the torques to their limits at 250 Hz (two arms, Traj. 2, docs/mujoco.md "Several
    #: arms on one cart")
    implicit_damping: bool = True
    #: Cartesian stiffness (N m/rad) and damping (N m s/rad) holding the hand's roll and pitch (about the world's
    #: horizontal axes) at the command's ``hand_target``: the grip keeps the cart upright against the roll
    #: moment of a lateral push at the handle's height; 0 = off. It leaves the planar push alone.
    tilt_stiffness: float = 0.0
    tilt_damping: float = 0.0
    #: Cartesian stiffness (N/m) and damping (N s/m) pulling the hand's position toward the command's
    #: ``hand_target`` (its velocity: the target's change over the period); 0 = off (pure wrench control)
    cartesian_stiffness: float = 0.0
    cartesian_damping: float = 0.0
    #: force loop: ``J^T K_f (e + K_i int e)``, ``e = w - w_f``, ``w_f`` the measured hand wrench (at the grasp,
    #: world-aligned) low-passed with time constant ``force_filter_tau`` (s), every physics step; it divides the
    #: arm's own task-space inertia and friction felt by the cart by ``1 + K_f`` and removes their slow part
    #: (``K_i``, 1/s); ``force_feedback`` 0 = off (open-loop J^T w). The loop's one-step delay and its measurement
    #: filter bound the gain. In the simplest model the hand delivers ``G`` times a change of the loop's wrench in the
    #: next physics step (1 along a
    #: direction the handle does not move, about ``m / (m + Lambda)`` along one the cart moves with the hand, ``m`` the
    #: cart's and ``Lambda`` the arm's task-space inertia: 20 and 19 kg along the push), and the filter passes ``a =
    #: dt / (tau + dt)`` of it, so the loop's pole is ``1 - a - a G K_f``: -1 at ``K_f = (2 - a) / (a G)``, 6 with
    #: 5 ms at ``G = 1``; with 2 ms instead (``a`` 0.5) K_f = 4 diverges (two arms, Traj. 2, seed 0, first 8 s: 316 %
    #: of the hand force). At 5 the pole is -0.71 where ``G = 1`` (0.18 left after a period). Measured in
    #: docs/mujoco.md "Several arms on one cart"
    force_feedback: float = 5.0
    #: the loop's gain on the moment rows (``K_f`` stands for the force rows): the wrist's rotational task-space
    #: inertia (0.3-0.6 kg m^2 for the iiwa, 0.004 for TIAGo) is too small to filter the loop's one-step delay;
    #: measured, TIAGo's moment loop at 3 drives its 3 N m wrist to 10x its limit
    moment_feedback: float = 1.0
    force_integral: float = 5.0
    force_filter_tau: float = 0.005
    #: time constant (s) of the F/T's part in the measured wrench: the loop takes the arm's joint-side estimate
    #: (`TorqueArmLaw.joint_torque_sample`) plus the reading's difference to it low-passed with this time constant;
    #: 0 = the F/T reading alone (its noise then enters the loop). The F/T's white noise passes as ``sigma sqrt(dt /
    #: 2 tau)`` per axis (0.039 N at 6 s, 0.067 N at 2 s), a slow wander the loop pushes into the cart; with the
    #: joint-space fusion what it corrects (the joint torque sensors' offsets, assumed to drift over minutes) stays put as
    #: the arm moves, and the correction starts from the samples of the settling before the push (`TorqueArmLaw.tare`),
    #: so a slow correction costs nothing. Measured (two arms, Traj. 2, seed 0, first 10 s, K_f = 4): 6 s 8.5 %,
    #: 2 s 8.7 % of the hand force
    fusion_tau: float = 6.0
    #: where the F/T's slow part corrects the joint-side estimate: "joint" (each joint torque's offset, which stays
    #: one as the arm moves and the base turns) or "hand" (the hand's wrench, in `fusion_frame`: a joint torque offset
    #: maps to a hand wrench that changes with the posture, and the correction lags each change by ``fusion_tau``).
    #: Measured (`cartpush push --plant mujoco --trajectory 2 --json --seed S`, S = 0/1/2; docs/mujoco.md "Wrench
    #: error"): "joint" 6.0/5.7/5.4 % of the hand force; "hand" in the world frame 7.4/12.4/18.0 % (the joint side's
    #: offset at the hand, about 20 N, turns with the base: 5 N of lag in each turn), in the mount frame 12.0 % (S = 2)
    fusion_space: str = "joint"
    #: the frame in which the hand-space fusion keeps the F/T's slow correction ``LP(w_FT - w_j)``: "mount" (the link
    #: the arm is mounted on, which turns with the base: the joint torque offsets' wrench at the hand stays put in it
    #: while the posture holds) or "world" (world-aligned: the correction lags a turn of the base by ``fusion_tau``,
    #: an error of the rotation rate x ``fusion_tau`` x the offset)
    fusion_frame: str = "mount"
    #: True: the plan term of modes "smoothed" and "refreshed" (the command's planned inertial torque) acts in the
    #: hand's null space only (``N^T``): it holds the posture, and the hand's wrench is ``J^T w`` and the force
    #: loop's. Its task-space part is the inertial torque of the *planned* hand motion, which the welded hand does
    #: not follow; the loop then has to cancel it. Measured (Traj. 1, default cart, seed 0, docs/mujoco.md "Wrench
    #: error"): wrench error 12.5 % with it in full, 9.6 % in the null space (the joint torque sensing exact)
    plan_null_space: bool = True
    #: True: the joint-side estimate weighs each joint's torque by 1 / effort_limit^2 (a weighted least squares:
    #: a joint torque sensor's noise scales with its range); False: unweighted
    weighted_estimate: bool = True
    #: the joint torque sensors' white noise per sample, as a fraction of each joint's effort limit, and the wrist
    #: F/T's (N, N m per sample): the joint-side estimate is the weighted least-squares wrench of both samples
    #: (`fused_estimator`), so where the joint torques do not see the hand's wrench (a straight elbow: a push along
    #: the arm loads no joint) it takes the F/T's reading instead of the joint torques' noise and offsets divided by a
    #: vanishing singular value (the 90 kg wheelchair, Traj. 1, joint side alone: thousands of N at a straight elbow,
    #: the law's request 62-126 times a limit). The F/T's moments are left out (``inf``): at the grasp they carry its
    #: force noise times the lever from the sensor and the tool's inertia (with 0.3 N m: Traj. 2 seed 0's wrench error
    #: 53 %). None: the joint torques alone (`wrench_estimator`). Measured with `reference_model`: docs/mujoco.md
    #: "Arm laws"
    joint_torque_noise: float = 0.001
    ft_noise: tuple[float, float] | None = (3.0, math.inf)
    #: True: the loop compares the measured wrench with the allocated one passed through what the measurement sees of
    #: it (one physics step late, low-passed with ``force_filter_tau``: `TorqueArmLaw.reference`), so a jump of the
    #: allocation between periods, which ``J^T w`` delivers at once, meets no proportional kick; False: the
    #: allocated wrench itself (a jump ``dw`` then gets ``K dw`` on top of ``J^T dw`` until the measurement sees it).
    #: Measured (`cartpush push --plant mujoco --trajectory 2 --json --seed S`, S = 0/1/2, with the fused estimate):
    #: wrench error 10.1/11.1/18.5 % of the hand force, the request 0.89/0.63/0.52 of a limit; without both (the
    #: joint side alone, no reference model): 16.9/15.9/32.1 %, 1.39/0.59/2.29
    reference_model: bool = True
    #: True: the law's request stays within the effort limits by priority (`TorqueArmLaw._prioritized`: the task
    #: part whole when it fits, else the closest wrench that does; the hand's feedback the closest wrench that fits in
    #: the room left, `fit_in_limits`; the posture clipped per joint into what remains); False: the sum is clipped per
    #: joint (each joint's full effort). On by default: with the base held at its place (`PushController`), the
    #: 90 kg wheelchair (examples/carts/wheelchair.xml, Traj. 1, seeds 0/1/2) and the default cart's Traj. 2 run the
    #: same with it as without (the request stays below the limits), and the hospital bed's request 1.10 of a limit
    #: becomes 1.00 at the same tracking
    budget: bool = True
    #: the arm's own inertia under the hand's predicted acceleration in the task part (`hand_inertia_terms` of the
    #: command's ``hand_acceleration``, `RobotCommand`): the torque that moves the arm with its base and its hand with
    #: the handle, which the push would otherwise give (the arm's task-space inertia at the grip, 19 kg along the push
    #: for the iiwa). "measured": with the base's acceleration of the last physics step (the base's servos jerk it at
    #: every new twist command, which no plan knows); "planned": the command's ``base_acceleration``; "off": left to
    #: the force loop. Measured (two Ridgebacks, Traj. 1, seed 0, first 10 s): wrench error 14.4 / 15.5 / 16.3 % of
    #: the hand force
    hand_inertia: str = "measured"
    #: time constant (s) of the joint torque sensors' part in the external joint torque: ``tau_ext = (M qdd + b) -
    #: (tau_cmd + LP(tau_joint - tau_cmd))``, the law's own command (the motor's torque, known without noise) plus
    #: the sensors' slow difference to it (the joints' friction and damping, the sensors' offsets), a complementary
    #: filter (`TorqueArmLaw.joint_torque_sample` with the sensors' reading); the sensors' white noise passes as
    #: ``sqrt(a / (2 - a))`` of it per sample, ``a = dt / (tau + dt)`` (0.07 at 0.2 s); 0 = the sensors' reading alone
    motor_torque_tau: float = 0.2
    #: True: while the hand holds the handle, the task part gives back the hand-space part of the joints' modelled
    #: viscous damping (``J^T Jbar^T D v``, ``D`` the robot model's joint damping, `TorqueArmLaw`'s
    #: ``joint_damping``: the URDF's ``<dynamics damping>``, 0.5 N m s/rad per iiwa joint): the damping the push
    #: would otherwise lose to the hand's motion relative to the base, which the force loop meets as a slow
    #: disturbance (the joints' velocities, 0.1-2 Hz). The null space keeps the joints' damping (and the posture
    #: impedance's), and a released hand keeps all of it: a force-controlled arm in free space has no other damping on
    #: the hand's directions. False: all of it left to the force loop. Measured (`cartpush push --plant mujoco --arms
    #: 2 --trajectory T --seed S --json`; docs/mujoco.md "Several arms on one cart"): two arms' wrench error 13.8 /
    #: 14.8 / 10.6 % of the hand force (T2 S0, T2 S1, T1 S0) becomes 10.1 / 10.9 / 10.9 %; one arm's stays (4.4-4.5 %
    #: on T2, 7.9-8.2 % on T1)
    passive_feedforward: bool = True


def hand_inertia_terms(
    M_aa: np.ndarray, M_ab: np.ndarray, J_a: np.ndarray, J_b: np.ndarray, jdot_qdot: np.ndarray, a_hand: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(t, K)`` with `hand_inertia_torque` ``= t + K a_base``: ``t = J_a^T Lambda (a_hand - Jdot qdot)``,
    ``K = M_ab - J_a^T Lambda J_b`` (the base's acceleration enters once per physics step, `TorqueArmLaw.torque`)."""
    x = np.asarray(a_hand, dtype=float) - np.asarray(jdot_qdot, dtype=float)
    A = J_a @ _solve(M_aa, J_a.T)
    A_reg = A + 1e-9 * float(np.trace(A)) / A.shape[0] * np.eye(A.shape[0])
    lam = _inv(A_reg)
    return J_a.T @ (lam @ x), M_ab - J_a.T @ lam @ J_b


def hand_inertia_torque(
    M_aa: np.ndarray,
    M_ab: np.ndarray,
    J_a: np.ndarray,
    J_b: np.ndarray,
    jdot_qdot: np.ndarray,
    a_hand: np.ndarray,
    a_base: np.ndarray,
) -> np.ndarray:
    """Return the arm's inertial joint torque ``M_aa qdd_a + M_ab a_base`` that gives the hand the acceleration
    `a_hand` (6: the grasp point's classical linear acceleration and the hand's angular acceleration, world-aligned)
    while the base's joints accelerate by `a_base`.

    The arm's rows of the robot's dynamics, ``M_aa qdd_a + M_ab qdd_b + b_a = tau + J_a^T f`` (``f`` the wrench on
    the hand), give the hand's wrench ``J^T w`` on the cart exactly when ``tau = J_a^T w + b_a + M_aa qdd_a + M_ab
    qdd_b``. Of the joint accelerations with ``J_a qdd_a = a_hand - J_b a_base - Jdot qdot`` (`jdot_qdot`: the hand's
    velocity-product acceleration) this takes the one of least kinetic energy, ``qdd_a = M_aa^-1 J_a^T Lambda x``,
    ``Lambda = (J_a M_aa^-1 J_a^T)^-1`` (Khatib's operational-space inertia): ``M_aa qdd_a = J_a^T Lambda x``, no
    null-space motion (the posture's impedance keeps that). ``M_aa`` (n, n), ``M_ab`` (n, n_b) the arm's rows of the
    joint-space inertia, ``J_a`` (6, n), ``J_b`` (6, n_b) the hand's Jacobian on the arm's and the base's joints.
    """
    t, K = hand_inertia_terms(M_aa, M_ab, J_a, J_b, jdot_qdot, a_hand)
    return t + K @ np.asarray(a_base, dtype=float)


def null_space_projector_T(J: np.ndarray, M: np.ndarray, Minv: np.ndarray | None = None) -> np.ndarray:
    """Return N^T = I - J^T Jbar^T, the dynamically consistent null-space projector of joint torques (`Minv`:
    ``M^-1`` when the caller has it)."""
    Minv = _inv(M) if Minv is None else Minv
    lam = _inv(J @ Minv @ J.T + 1e-9 * np.eye(J.shape[0]))
    Jbar = Minv @ J.T @ lam
    return np.eye(M.shape[0]) - J.T @ Jbar.T


def implicit_impedance(
    NT: np.ndarray, M: np.ndarray, damping: float, dt: float, Minv: np.ndarray | None = None
) -> np.ndarray:
    """Return ``A = (I + dt N^T D M^-1)^-1 N^T``: the joint impedance ``tau = A (K (q_plan - q) + D (v_plan - v))``
    with its damping on the velocity at the end of the physics step, ``v + dt M^-1 tau`` (semi-implicit; ``D = d I``).

    ``tau = N^T (K e + D (v_plan - v - dt M^-1 tau))`` solved for ``tau``: on a motion of inertia ``I`` the explicit
    damping's step response ``1 - D dt / I`` turns unstable below ``I = D dt / 2``; here it is ``1 / (1 + D dt / I)``,
    stable for any inertia, and where ``D dt`` is small against the inertia (the posture's usual motions) the law is
    the explicit one. ``A`` keeps ``tau`` in the range of ``N^T`` (the hand's null space). `Minv`: ``M^-1`` when the
    caller has it."""
    n = M.shape[0]
    return _solve(np.eye(n) + dt * damping * NT @ (_inv(M) if Minv is None else Minv), NT)


def wrench_estimator(J: np.ndarray, effort_limit: np.ndarray | None = None) -> np.ndarray:
    """Return E with ``w = E tau``: the least-squares wrench of joint torques ``tau = J^T w`` (6 x n).

    With `effort_limit`, each joint's torque is weighted by ``1 / limit^2`` (``E = (J W J^T)^-1 J W``), as a joint
    torque sensor's noise scales with its range; without, ``E = (J J^T)^-1 J``.
    """
    W = np.ones(J.shape[1]) if effort_limit is None else 1.0 / np.asarray(effort_limit, dtype=float) ** 2
    JW = J * W
    reg = 1e-9 * float(np.max(W))
    return np.linalg.solve(JW @ J.T + reg * np.eye(J.shape[0]), JW)


def fused_estimator(J: np.ndarray, sigma_tau: np.ndarray, sigma_ft: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (E, F) with ``w = E tau + F w_ft``: the weighted least-squares wrench of one joint torque sample
    ``tau = J^T w + n_tau`` and one F/T sample ``w_ft = w + n_ft`` (white noises of standard deviations `sigma_tau`
    per joint, `sigma_ft` per wrench axis; the Gaussian maximum-likelihood estimate):

    ``w = (J W J^T + R)^-1 (J W tau + R w_ft)``, ``W = diag(sigma_tau^-2)``, ``R = diag(sigma_ft^-2)``.

    Where ``J`` is well conditioned the joint torques decide (their noise reaches the hand far smaller than the
    F/T's); along a direction the joints do not see (``J^T`` loses rank at a straight elbow) the F/T does, and the
    estimate stays bounded where the joint side alone (`wrench_estimator`) divides the joint torques' noise and
    offsets by a vanishing singular value.
    """
    W = 1.0 / np.asarray(sigma_tau, dtype=float) ** 2
    R = np.diag(1.0 / np.asarray(sigma_ft, dtype=float) ** 2)  # an infinite sigma: that axis's F/T left out
    A = (J * W) @ J.T + R
    return _solve(A, J * W), _solve(A, R)


def net_wrench_projector(points: np.ndarray) -> np.ndarray:
    """Return ``P = G^+ G`` (6n x 6n): the stacked hand wrenches' part that moves the cart's net wrench.

    ``G = [G_1 ... G_n]`` (6 x 6n) maps the hands' wrenches (world-aligned ``[f; n]`` at the grasp points
    `points`, (n, 3)) to the net wrench on the rigid cart, ``G_i = [[I, 0], [[p_i - c]x, I]]`` (the spatial form of
    the paper's grasp map, eqs. 23-25; ``c`` the points' mean, which leaves ``P`` unchanged). ``I - P`` keeps the
    null space of ``G``: the internal wrench (the squeeze between the hands), which no motion of the cart shows.
    ``P`` is the orthogonal projector onto the range of ``G^T`` (forces in N, moments in N m); with one hand it is
    the identity.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    c = p.mean(axis=0)
    G = np.zeros((6, 6 * len(p)))
    for i, r in enumerate(p - c):
        G[:, 6 * i : 6 * i + 6] = np.eye(6)
        G[3:, 6 * i : 6 * i + 3] = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    return G.T @ _solve(G @ G.T, G)


def damped_pinv(J: np.ndarray, damping: float) -> np.ndarray:
    """Return J^T (J J^T + damping I)^-1."""
    return J.T @ np.linalg.inv(J @ J.T + damping * np.eye(J.shape[0]))


def torque_budget(task: np.ndarray, extra: np.ndarray, limit: np.ndarray) -> float:
    """Return the largest ``s`` in [0, 1] with ``|task + s extra| <= limit`` on every joint (0 if `task` exceeds one).

    The torque law's priority: the task part (``J^T w`` + the bias forces: the allocated wrench and the arm's
    weight) first, the feedback and posture terms scaled down together to what the limits leave, so the request
    stays within them without a clip that would bend the hand's wrench. A task part beyond a limit is the
    allocation's (its torque rows, `WrenchAllocator.set_torque_limits`).
    """
    room_hi = limit - task
    room_lo = -limit - task
    if np.any(room_hi < 0.0) or np.any(room_lo > 0.0):
        return 0.0
    scale = 1.0
    up, down = extra > 0.0, extra < 0.0
    if np.any(up):
        scale = min(scale, float(np.min(room_hi[up] / extra[up])))
    if np.any(down):
        scale = min(scale, float(np.min(room_lo[down] / extra[down])))
    return max(scale, 0.0)


def fit_in_limits(A: np.ndarray, x: np.ndarray, base: np.ndarray, limit: np.ndarray) -> np.ndarray | None:
    """Return the ``x'`` closest to `x` with ``|base + A x'| <= limit`` on every joint (`x` itself when it fits), or
    None when `base` alone exceeds a limit.

    A box-constrained least squares (daqp): ``min |diag(1/limit) A (x' - x)|^2`` (each joint's torque change relative
    to its range; a ridge of 1e-9 of the mean curvature makes directions ``A`` does not see keep ``x``). With ``A =
    J^T`` and ``x`` a hand wrench, ``A x'`` stays a hand wrench (a per-joint clip, the same least squares without
    that constraint, adds torques in the hand's null space and bends the wrench by whatever the clipped joints
    held); where a uniform scale ``s x`` (`torque_budget`) drops all of ``x`` as soon as one joint has no room, the
    fit keeps the axes the other joints can still give. Solver failure: the uniform scale.
    """
    if (np.abs(base + A @ x) <= limit).all():
        return x
    if (np.abs(base) > limit).any():
        return None
    D = A / limit[:, None]
    H = D.T @ D
    H += 1e-9 * float(np.trace(H)) / H.shape[0] * np.eye(H.shape[0])
    sol, _, flag, _ = daqp.solve(H, -H @ x, np.ascontiguousarray(A), limit - base, -limit - base)
    if flag < 1:
        return torque_budget(base, A @ x, limit) * x
    return np.asarray(sol, dtype=float)


def _joint_damping(joint_damping: np.ndarray | None, n: int) -> np.ndarray:
    """Return the joints' viscous damping as an array of `n` values >= 0 (zeros for None); ValueError otherwise."""
    if joint_damping is None:
        return np.zeros(n)
    D = np.asarray(joint_damping, dtype=float)
    if D.shape != (n,) or np.any(D < 0.0):
        raise ValueError(f"joint_damping must give one damping >= 0 per joint ({n}), got {joint_damping}")
    return D


def _within(tau: np.ndarray, limit: np.ndarray) -> bool:
    """Return ``(|tau| <= limit).all()`` (the test of `fit_in_limits`; as a list: a numpy reduction costs 1 us)."""
    return False not in (np.abs(tau) <= limit).tolist()


def _clip(tau: np.ndarray, limit: np.ndarray, neg_limit: np.ndarray | None = None) -> np.ndarray:
    """Return ``np.clip(tau, -limit, limit)`` (its arithmetic without its per-call wrapping; `neg_limit`: ``-limit``)."""
    return np.minimum(np.maximum(tau, -limit if neg_limit is None else neg_limit), limit)


class TorqueArmLaw:
    """The torque law of one arm (see the module docstring); `begin` once per period, `torque` each physics step."""

    def __init__(
        self,
        effort_limit: np.ndarray,
        gains: TorqueArmGains = TorqueArmGains(),
        physics_dt: float = 0.002,
        joint_damping: np.ndarray | None = None,
    ) -> None:
        """`joint_damping`: the joints' viscous damping ``D`` (N m s/rad per joint) of the robot's model (its URDF's
        ``<dynamics damping>``; None: none), the law's model of the joints' passive torque ``-D v``."""
        self._set_limits(effort_limit, joint_damping)
        #: the joints' modelled passive torque ``-D v`` at the last step's velocity (`torque`)
        self._passive = np.zeros(self.limit.size)
        #: ``J^T Jbar^T``: the hand-space part of a joint torque (`begin`)
        self._task_proj = np.zeros((self.limit.size, self.limit.size))
        self.gains = gains
        self._alpha = physics_dt / (gains.force_filter_tau + physics_dt)
        self._dt = physics_dt
        self._w_d = np.zeros(6)
        self._w_f: np.ndarray | None = None
        self._integral = np.zeros(6)
        self._saturated = False
        #: the joint-side wrench estimate of the last step and the low-passed F/T minus it
        self._w_joint: np.ndarray | None = None
        self._ft_offset = np.zeros(6)
        self._n_fused = 0
        #: the rotation (world from the arm's mount link) at the last joint torque sample (`fusion_frame` "mount")
        self._mount = np.eye(3)
        #: the last external joint torque sample and the low-passed error of the joint torques (fusion "joint")
        self._tau_ext: np.ndarray | None = None
        self._tau_offset = np.zeros(self.limit.size)
        #: the torque the law commanded for the last physics step and the low-passed sensed-minus-commanded joint
        #: torque (`TorqueArmGains.motor_torque_tau`)
        self._tau_cmd: np.ndarray | None = None
        self._tau_friction = np.zeros(self.limit.size)
        self._n_motor = 0
        self._Jt_pinv = self._neg_Jt_pinv = np.zeros((6, self.limit.size))
        self._E_ft = np.zeros((6, 6))
        self._gain = np.r_[np.full(3, gains.force_feedback), np.full(3, gains.moment_feedback)]
        self._ff = np.zeros(self.limit.size)
        self._bias0: np.ndarray | None = None
        #: the command's plan term (arm_torque - J^T w - b_0), low-passed over the periods (mode "smoothed")
        self._plan: np.ndarray | None = None
        self._plan_period = np.zeros(self.limit.size)  # `_plan_ff` of the period (fixed from its first step on)
        self._Jw = np.zeros(self.limit.size)
        self._arm_torque = np.zeros(self.limit.size)
        self._period = 0.01
        self._NT = np.eye(self.limit.size)
        self._NT_imp = self._NT
        self._q_end = np.zeros(self.limit.size)
        self._v = np.zeros(self.limit.size)
        self._t_end = 0.0
        self._reset_records()
        #: the loop's reference: the allocated wrench as the measurement sees it (`reference`)
        self._w_ref: np.ndarray | None = None
        self._w_d_prev: np.ndarray | None = None
        self.a_plan = np.zeros(self.limit.size)
        self._started = False
        #: the arm's inertial torque under the hand's predicted acceleration (`begin`): (t, K, planned base acceleration)
        self._inertial_terms: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def _set_limits(self, effort_limit: np.ndarray, joint_damping: np.ndarray | None) -> None:
        """Take the effort limits and the joints' damping (`_joint_damping`), and their negatives (used every step)."""
        self.limit = np.asarray(effort_limit, dtype=float)
        self.joint_damping = _joint_damping(joint_damping, self.limit.size)
        self._neg_damping, self._neg_limit = -self.joint_damping, -self.limit

    def _reset_records(self) -> None:
        """Start the records of the law's request against the limits, before any clip: the peak over all joints, per
        joint, and the task part's (``J^T w + b``) peak; physics steps whose request exceeds a limit (then clipped:
        the task part alone exceeds it) and steps where the budget scaled the feedback down."""
        self.peak_ratio = 0.0
        self.peak_joint_ratio = np.zeros(self.limit.size)
        self.peak_task_ratio = 0.0
        self.saturated_steps = 0
        self.scaled_steps = 0
        self.saturated_now = False

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
        inertial: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """Take the period's command, the hand Jacobian (6, n), the arm inertia (n, n); the period of `dt` ends at `t_end`.

        `inertial`: ``(t, K, a_base)``, the arm's inertial torque ``t + K a_base`` under the hand's predicted
        acceleration (`hand_inertia_terms`) and the base's planned acceleration, in the task part
        (`TorqueArmGains.hand_inertia`); None: zero."""
        v_new = np.asarray(arm_velocity, dtype=float)
        self.a_plan = (v_new - self._v) / dt if self._started else np.zeros_like(v_new)
        self._started = True
        self._w_d = np.asarray(hand_wrench, dtype=float)
        if self.gains.feedforward in ("bias", "dynamics"):
            self._ff = J.T @ np.asarray(hand_wrench, dtype=float)
        else:
            self._ff = np.asarray(arm_torque, dtype=float)
        self._q_end = np.asarray(arm_position, dtype=float)
        self._bias0 = None
        self._arm_torque = np.asarray(arm_torque, dtype=float)
        self._Jw = J.T @ np.asarray(hand_wrench, dtype=float)
        self._period = dt
        self._v = v_new
        Minv = _inv(M)
        NT = null_space_projector_T(J, M, Minv)
        self._task_proj = np.eye(M.shape[0]) - NT
        self._NT = NT if self.gains.null_space else np.eye(M.shape[0])
        self._NT_imp = self._NT
        if self.gains.implicit_damping:
            self._NT_imp = implicit_impedance(self._NT, M, self.gains.damping, self._dt, Minv)
        self._J = J
        self._set_estimator(J)
        self._Jr = J[3:]
        self._Jt = J[:3]
        self._t_end = t_end
        self._inertial_terms = None if self.gains.hand_inertia == "off" else inertial

    def torque(
        self,
        t: float,
        q: np.ndarray,
        v: np.ndarray,
        bias: np.ndarray,
        tilt: tuple[np.ndarray, np.ndarray] | None = None,
        hand: tuple[np.ndarray, np.ndarray] | None = None,
        wrench_measured: np.ndarray | None = None,
        loop_wrench: np.ndarray | None = None,
        base_acceleration: np.ndarray | None = None,
        grasped: bool = True,
    ) -> np.ndarray:
        """Return the joint torques at time `t` and state (q, v), within limits (clipped, or `TorqueArmGains.budget`).

        `base_acceleration`: the base joints' measured acceleration over the last physics step, for the arm's
        inertial torque with `TorqueArmGains.hand_inertia` "measured" (None: the planned one). `grasped`: the hand
        holds the handle (the gripper closed on it); only then does the task part give back the hand-space part of
        the joints' modelled damping (`TorqueArmGains.passive_feedforward`) and the force loop's wrench apply.

        `hand`: (target position - hand position, target velocity - hand velocity), world frame, for the
        Cartesian impedance (None: off).

        `bias`: the arm's bias forces there; `tilt`: (rotation error hand -> target, hand angular velocity), world
        frame, for the roll/pitch hold (None: off); `wrench_measured`: the F/T reading at the grasp, world-aligned,
        for the force loop (None: off); `loop_wrench`: the loop's wrench given from outside instead (`force_loop`
        of `force_error`, the part in the cart's net wrench with several arms on one cart: `net_wrench_projector`).
        """
        g = self.gains
        if loop_wrench is None and wrench_measured is not None and g.force_feedback > 0.0:
            loop_wrench = self.force_loop(self.force_error(wrench_measured))
        task, plan = self._feedforward(g, bias)
        task = task + self._inertial_torque(base_acceleration)
        self._passive = self._neg_damping * v
        if grasped and g.passive_feedforward:
            task = task - self._task_proj @ self._passive
        q_plan = self._q_end - self._v * (self._t_end - t)
        impedance = self._NT_imp @ (g.stiffness * (q_plan - q) + g.damping * (self._v - v))
        u = self._hand_feedback(g, hand, loop_wrench if grasped else None, tilt)
        posture = plan + impedance
        if g.budget:
            tau = self._prioritized(task, u, posture)
        else:
            tau = task + self._J.T @ u + posture
            self._record(task, tau, False, False)
        if self.saturated_now:
            tau = _clip(tau, self.limit)
        self._tau_cmd = tau
        return tau

    def _hand_feedback(
        self,
        g: TorqueArmGains,
        hand: tuple[np.ndarray, np.ndarray] | None,
        loop_wrench: np.ndarray | None,
        tilt: tuple[np.ndarray, np.ndarray] | None,
    ) -> np.ndarray:
        """Return the hand's feedback wrench (world-aligned at the grasp; the arm applies ``J^T`` of it): the
        Cartesian impedance's force, the force loop's wrench and the tilt hold's roll and pitch moments."""
        u = np.zeros(6)
        if hand is not None:
            p_err, v_err = hand
            u[:3] += g.cartesian_stiffness * p_err + g.cartesian_damping * v_err
        if loop_wrench is not None and g.force_feedback > 0.0:
            u += loop_wrench
        if tilt is not None and (g.tilt_stiffness > 0.0 or g.tilt_damping > 0.0):
            err, omega = tilt
            n = g.tilt_stiffness * err - g.tilt_damping * omega
            u[3:5] += n[:2]  # roll and pitch only: the yaw torque is the allocation's
        return u

    def _prioritized(self, task: np.ndarray, u: np.ndarray, posture: np.ndarray) -> np.ndarray:
        """Return the law's torque within the effort limits, by priority (`TorqueArmGains.budget`, `fit_in_limits`).

        1. the task part ``J^T w + b``: whole if it fits, else the allocated wrench bent to the closest that fits
           (clipped only when the bias forces alone exceed a limit);
        2. the hand's feedback ``J^T u``: the wrench closest to ``u`` that fits in the room the task part leaves;
        3. the posture (plan term and joint impedance) clipped per joint into the room left.
        """
        L, Jt = self.limit, self._J.T
        base = task - self._Jw  # the task part besides J^T w: the bias forces (and the plan's, modes "command"...)
        w_fit: np.ndarray | None = self._w_d
        task_fit = base + Jt @ self._w_d  # fit_in_limits' own test, kept for the common case where it fits
        if not _within(task_fit, L):
            w_fit = fit_in_limits(Jt, self._w_d, base, L)
            task_fit = _clip(task, L) if w_fit is None else base + Jt @ w_fit
        u_fit: np.ndarray | None = u
        tau = task_fit + Jt @ u
        if not _within(tau, L):
            u_fit = fit_in_limits(Jt, u, task_fit, L)
            u_fit = np.zeros(6) if u_fit is None else u_fit
            tau = task_fit + Jt @ u_fit
        wanted = tau + posture
        held = _clip(wanted, L, self._neg_limit)
        trimmed = w_fit is not self._w_d or u_fit is not u
        self._record(task, held, trimmed, True in (held != wanted).tolist())
        return held

    def _feedforward(self, g: TorqueArmGains, bias: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the feed-forward as (task part ``J^T w + b``, plan part; `TorqueArmGains.feedforward`).

        Modes "command" and "dynamics" hold the planned inertial torque inside the task part.
        """
        if g.feedforward in ("refreshed", "smoothed"):
            if self._bias0 is None:  # the period's first step: the bias forces inside the command's torque
                self._bias0 = np.asarray(bias, dtype=float).copy()
                self._plan = self._plan_term(g, self._bias0)
                self._plan_period = self._plan_ff(g, bias)  # fixed over the period (b_0, N^T and the plan are)
            return self._Jw + bias, self._plan_period
        zero = np.zeros(self.limit.size)
        return (self._ff, zero) if g.feedforward == "command" else (self._ff + bias, zero)

    def _inertial_torque(self, base_acceleration: np.ndarray | None) -> np.ndarray:
        """Return the arm's inertial torque ``t + K a_base`` (`hand_inertia_terms`) with the base's measured
        acceleration (`TorqueArmGains.hand_inertia` "measured", when given) or the planned one; zero without terms."""
        if self._inertial_terms is None:
            return np.zeros(self.limit.size)
        t, K, planned = self._inertial_terms
        measured = self.gains.hand_inertia == "measured" and base_acceleration is not None
        return t + K @ (np.asarray(base_acceleration, dtype=float) if measured else planned)

    def _record(self, task: np.ndarray, tau: np.ndarray, trimmed: bool, posture_held: bool) -> None:
        """Keep the step's request against the limits: peaks (all joints, per joint, task part) and counts.

        `trimmed`: the budget bent the allocated wrench or the hand's feedback to fit (the integral then holds).
        """
        ratio = np.abs(tau) / self.limit
        self.peak_joint_ratio = np.maximum(self.peak_joint_ratio, ratio)
        largest = max(ratio.tolist())  # the reductions of a few joints as Python floats (a numpy one costs 1 us)
        self.peak_ratio = max(self.peak_ratio, largest)
        self.peak_task_ratio = max(self.peak_task_ratio, max((np.abs(task) / self.limit).tolist()))
        self.saturated_now = largest > 1.0
        self._saturated = trimmed or self.saturated_now
        self.saturated_steps += int(self.saturated_now)
        self.scaled_steps += int(trimmed or posture_held)

    def _plan_ff(self, g: TorqueArmGains, bias: np.ndarray) -> np.ndarray:
        """Return the feed-forward's plan part besides ``J^T w + b``: ``arm_torque - J^T w - b_0`` raw ("refreshed")
        or low-passed ("smoothed"), in the hand's null space (``N^T``) when `TorqueArmGains.plan_null_space`."""
        assert self._bias0 is not None and self._plan is not None
        plan = self._arm_torque - self._Jw - self._bias0 if g.feedforward == "refreshed" else self._plan
        return self._NT @ plan if g.plan_null_space else plan

    def _plan_term(self, g: TorqueArmGains, bias0: np.ndarray) -> np.ndarray:
        """Return the command's plan term ``arm_torque - J^T w - b_0`` (its planned inertial torque), low-passed."""
        d = self._arm_torque - self._Jw - bias0
        a = self._period / (g.plan_filter_tau + self._period)
        return d if self._plan is None else self._plan + a * (d - self._plan)

    def joint_torque_sample(
        self,
        tau_ext: np.ndarray,
        mount: np.ndarray | None = None,
        joint_torque: np.ndarray | None = None,
    ) -> None:
        """Take the arm's external joint torque over the last physics step (``J^T`` of the cart's wrench on the hand).

        ``tau_ext = (M qdd)_arm + b - tau_joint``: what the joint torque sensors, the accelerations and the model
        say the rest of the world applied to the arm (the caller computes it). The hand's wrench on the cart is
        the weighted least squares of it and the F/T's reading (`joint_estimate`). `mount`: the rotation (world
        from the link the arm is mounted on) at the sample, the frame of the F/T's slow correction
        (`TorqueArmGains.fusion_frame`); None: the last one given (the identity at first). `joint_torque`: the
        sensors' reading ``tau_joint`` itself; with it and `TorqueArmGains.motor_torque_tau` the sensed joint torque
        is the law's last command plus the joints' modelled passive torque (``-D v`` at the step's velocity, ``D``
        the law's ``joint_damping``) plus the reading's low-passed difference to both (`_motor_side`).
        """
        tau_ext = np.asarray(tau_ext, dtype=float)
        if joint_torque is not None and self.gains.motor_torque_tau > 0.0 and self._tau_cmd is not None:
            model = self._tau_cmd + self._passive
            tau_ext = self._motor_side(tau_ext, np.asarray(joint_torque, dtype=float), model)
        self._tau_ext = tau_ext
        if mount is not None:
            self._mount = np.asarray(mount, dtype=float).reshape(3, 3)
        self._w_joint = self._neg_Jt_pinv @ self._tau_ext

    def hold(self, J: np.ndarray, tau: np.ndarray, v: np.ndarray) -> None:
        """Take one physics step of the arm holding the handle still before the push (the plant's settling): the
        hand's Jacobian (6, n), the torque commanded for the step and the joint velocities at its start. The step's
        samples (`joint_torque_sample`, then `tare`) then start the sensors' slow parts (`_motor_side`,
        `_measured_wrench`) as a real arm zeroes its sensors before a task, instead of the push's first samples."""
        self._J = J
        self._set_estimator(J)
        self._tau_cmd = np.asarray(tau, dtype=float).copy()
        self._passive = -self.joint_damping * np.asarray(v, dtype=float)

    def tare(self, ft: np.ndarray) -> None:
        """Take the F/T reading (world-aligned at the grasp) of a step held before the push (`hold`, after
        `joint_torque_sample`) into the fusion's slow part; the loop's measured wrench and reference are left alone."""
        if self.gains.fusion_tau > 0.0 and self._w_joint is not None:
            self._measured_wrench(np.asarray(ft, dtype=float))

    def _motor_side(self, tau_ext: np.ndarray, joint_torque: np.ndarray, model: np.ndarray) -> np.ndarray:
        """Return ``tau_ext`` with the sensed joint torque replaced by the `model`'s (the last command and the
        joints' modelled damping) plus the low-passed sensed-minus-modelled torque (`TorqueArmGains.motor_torque_tau`;
        the low-pass starts as the running mean).

        The joint's torque is the motor's, which the law commands and so knows without noise, plus what the joint
        itself takes (its modelled damping, its unmodelled friction) and the sensor's offset: the unmodelled part is
        slow next to the sensor's white noise, so the sensor is needed only at low frequency (a complementary filter).
        """
        self._n_motor += 1
        gain = max(min(self._dt / self.gains.motor_torque_tau, 1.0), 1.0 / self._n_motor)
        self._tau_friction += gain * (joint_torque - model - self._tau_friction)
        return tau_ext + joint_torque - (model + self._tau_friction)

    def _measured_wrench(self, ft: np.ndarray) -> np.ndarray:
        """Return the hand's wrench the loop sees: the joint-side estimate + the F/T's slow part (or the F/T alone).

        `TorqueArmGains.fusion_space` "joint": ``w = -E (tau_ext - o)``, ``o`` the low-passed ``tau_ext + J^T w_FT``
        (each joint torque's error against what the F/T says it should read); "hand": ``w = w_j + R LP(R^T (w_FT -
        w_j))``, ``R`` the arm's mount rotation (`TorqueArmGains.fusion_frame` "mount"; the identity for "world").
        The low-pass (`fusion_tau`) starts as the running mean of the samples so far.
        """
        g = self.gains
        if g.fusion_tau <= 0.0 or self._w_joint is None or self._tau_ext is None:
            return ft
        self._n_fused += 1
        gain = max(min(self._dt / g.fusion_tau, 1.0), 1.0 / self._n_fused)
        if g.fusion_space == "joint":
            self._tau_offset += gain * (self._tau_ext + self._J.T @ ft - self._tau_offset)
            return self._E_ft @ ft - self._Jt_pinv @ (self._tau_ext - self._tau_offset)
        w_joint = self.joint_estimate(ft)
        R = self._mount if g.fusion_frame == "mount" else np.eye(3)
        diff = ft - w_joint
        self._ft_offset += gain * (np.r_[R.T @ diff[:3], R.T @ diff[3:]] - self._ft_offset)
        return w_joint + np.r_[R @ self._ft_offset[:3], R @ self._ft_offset[3:]]

    def joint_estimate(self, ft: np.ndarray) -> np.ndarray:
        """Return the hand's wrench from the last joint torque sample and the F/T's reading `ft` of the same step:
        ``w_j = -E tau_ext + F w_FT`` (`fused_estimator`; ``F = 0`` and ``E`` `wrench_estimator`'s without
        `TorqueArmGains.ft_noise`)."""
        assert self._w_joint is not None
        return self._w_joint + self._E_ft @ ft

    def _set_estimator(self, J: np.ndarray) -> None:
        """Take the joint-side estimate's matrices at the hand Jacobian `J` (`_estimator`), and ``-E`` for the
        per-step ``w_j = -E tau_ext``."""
        self._Jt_pinv, self._E_ft = self._estimator(J)
        self._neg_Jt_pinv = -self._Jt_pinv

    def _estimator(self, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the joint-side estimate's matrices (E, F): ``w_j = -E tau_ext + F w_FT`` (`TorqueArmGains.ft_noise`)."""
        g = self.gains
        if g.ft_noise is None:
            return wrench_estimator(J, self.limit if g.weighted_estimate else None), np.zeros((6, 6))
        scale = self.limit if g.weighted_estimate else np.full(self.limit.size, float(np.mean(self.limit)))
        sigma_ft = np.repeat(np.array(g.ft_noise[:2], dtype=float), 3)
        return fused_estimator(J, self._joint_noise_factor() * g.joint_torque_noise * scale, sigma_ft)

    def _joint_noise_factor(self) -> float:
        """Return the part of the joint torque sensors' white noise left in the sensed joint torque per sample: 1, or
        ``sqrt(a / (2 - a))``, ``a = dt / (motor_torque_tau + dt)``, through `_motor_side`'s low-pass."""
        tau = self.gains.motor_torque_tau
        if tau <= 0.0:
            return 1.0
        a = self._dt / (tau + self._dt)
        return math.sqrt(a / (2.0 - a))

    def reference(self) -> np.ndarray:
        """Return the force loop's reference: the allocated wrench as the loop's measurement sees it.

        `TorqueArmGains.reference_model`: the measured wrench of a physics step is the hand's response to the
        previous step's torque, low-passed (``force_filter_tau``); the reference is the allocated wrench through
        the same one-step delay and low-pass. ``J^T w`` delivers a jump of the allocation at once; compared with
        the jump itself the loop would add ``K`` times it before the measurement sees the hand respond (a kick of
        ``K + 1`` times the jump for one or two steps: 1.4 times it in the period mean, measured on Traj. 2's
        50-130 N jumps of the downward press). Call once per physics step.
        """
        if not self.gains.reference_model:
            return self._w_d
        prev = self._w_d if self._w_d_prev is None else self._w_d_prev
        self._w_ref = prev.copy() if self._w_ref is None else self._w_ref + self._alpha * (prev - self._w_ref)
        self._w_d_prev = self._w_d.copy()
        return self._w_ref

    def force_error(self, ft: np.ndarray) -> np.ndarray:
        """Return the force loop's error ``e = w - w_f`` of this physics step: the reference (`reference`) minus the
        measured hand wrench (`_measured_wrench` of the F/T reading `ft`, low-passed). Call once per physics step."""
        w = self._measured_wrench(np.asarray(ft, dtype=float))
        self._w_f = w.copy() if self._w_f is None else self._w_f + self._alpha * (w - self._w_f)
        return self.reference() - self._w_f

    def force_loop(self, e: np.ndarray, e_integral: np.ndarray | None = None) -> np.ndarray:
        """Return the loop's task-space wrench ``K (e + K_i int e_I)`` for the error `e` (`force_error`) and the
        error it integrates `e_integral` (default `e`; with several arms the error's part in the cart's net wrench:
        `net_wrench_projector`); the integral is held while saturated. ``K`` is ``K_f`` on the force rows,
        ``moment_feedback`` on the moment rows."""
        g = self.gains
        if g.force_integral > 0.0 and not self._saturated:
            self._integral += self._dt * (e if e_integral is None else e_integral)
        return self._gain * (e + g.force_integral * self._integral)
