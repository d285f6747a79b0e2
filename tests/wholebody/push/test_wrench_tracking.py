"""The torque law applies the allocated wrench: physics of the held hand (the iiwa on the Ridgeback, MuJoCo plant).

The cart is held still (a viscous clamp on its free joint: a 10 N push moves it at 0.1 mm/s) so the hand's wrench on
it is what the arm makes of the command; the period-mean of the noise-free F/T (what the cart integrates) is
compared with the allocated wrench.

- **Sensor noise** (base at rest, F/T with the loop's 3 N per sample): the fused loop passes the F/T's noise only
  through its slow part, a first-order filter of time constant ``T = fusion_tau``: per axis ``sigma sqrt(dt /
  (2 T))`` = 0.13 N at T = 0.5 s (``dt`` the physics step). The F/T fed back directly (10 ms filter, ``K_f = 2``) pushes its
  noise, filtered to ``sigma sqrt(dt / (2 tau))`` = 0.9 N per axis, into the cart ``K_f`` times over.
- **Moving base** (the base accelerates toward the cart at 0.5 m/s^2 for 0.6 s, no noise): the arm folds, its
  links' momentum takes newtons from the forward push open loop, a ramp as the fold speeds up (the joints' damping,
  which would push the other way, is given back: `TorqueArmGains.passive_feedforward`); the proportional loop
  divides it by ``1 + K_f``, and on a ramp of slope ``r`` the PI loop's error settles at ``r / (K_f K_i)``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from cart.simulate import MeasurementNoise
from wholebody.push import PushConfig, build_controller
from wholebody.push.arm_control import TorqueArmGains
from wholebody.push.config import TRUE_CART
from wholebody.push.mujoco_plant import JointTorqueNoise, MujocoPlant, MujocoPlantConfig
from wholebody.push.plant import RobotCommand

PUSH = np.array([10.0, 0.0, -5.0, 0.0, 0.0, 0.0])  # world-aligned at the grasp: forward and down
#: the F/T fed straight into a proportional loop (no joint-side estimate, no integral)
FT_ONLY = TorqueArmGains(
    feedforward="bias", force_feedback=2.0, force_integral=0.0, force_filter_tau=0.01, fusion_tau=0.0
)
#: the loop under test: the plant's bias forces as feed-forward (the commands here carry no arm_torque)
LOOP = TorqueArmGains(feedforward="bias")


@pytest.fixture(scope="module")
def setup():
    return build_controller(PushConfig(trajectory=1, duration=2.0, contact="fixed"))


def _held_cart_plant(
    setup, gains: TorqueArmGains, noise: MeasurementNoise, joint_noise: JointTorqueNoise = JointTorqueNoise(0.0, 0.0)
) -> MujocoPlant:
    """Return the plant with the cart clamped; the joint torque sensing exact unless `joint_noise` says otherwise."""
    config = MujocoPlantConfig(torque_gains=gains, joint_torque_noise=joint_noise)
    plant = MujocoPlant(setup.controller.robots, setup.q0, TRUE_CART, noise=noise, config=config)
    c = plant.scene.cart_dof  # a viscous clamp on the cart's free joint: 1e5 N s/m, under 10 N 0.1 mm/s
    plant.scene.model.dof_damping[c : c + 6] = 1e5
    return plant


def _push(plant: MujocoPlant, base_acceleration: float, duration: float) -> np.ndarray:
    """Return the period-mean hand force minus the allocated one (n_periods, 3) while the base accelerates along x."""
    first = plant.measure().robots[0]
    n = first.q_arm.size
    errors = []
    for k in range(int(round(duration / plant.dt))):
        r = plant.measure().robots[0]
        v = base_acceleration * (k + 1) * plant.dt
        cmd = RobotCommand(
            arm_velocity=np.zeros(n),
            arm_position=r.q_arm.copy(),  # the null-space posture follows the arm: no pull on the hand
            arm_torque=np.zeros(n),
            base_twist=np.array([v, 0.0, 0.0]),
            wheel_rates=np.zeros(4),
            hand_wrench=PUSH,
        )
        plant.step([cmd])
        errors.append(plant._hand_clean[0][:3] - PUSH[:3])
    return np.array(errors)


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))


def test_fused_force_loop_keeps_the_sensor_noise_out_of_the_push(setup):
    sigma = 3.0
    noise = MeasurementNoise(force=sigma, torque=0.1 * sigma)
    dt = MujocoPlantConfig().physics_dt
    # T = 0.5 s: the filter starts as the running mean of the samples so far (for the first T / dt of them), so the
    # 1 s run sees the first-order filter's steady state only with T well under 1 s
    gains = replace(LOOP, fusion_tau=0.5)
    fused = _rms(_push(_held_cart_plant(setup, gains, noise), 0.0, 1.0)[20:])
    direct = _rms(_push(_held_cart_plant(setup, FT_ONLY, noise), 0.0, 1.0)[20:])
    # what passes the fusion's slow F/T part, per axis, over three axes; twice for the torque noise's share
    passed = math.sqrt(3.0) * sigma * math.sqrt(dt / (2.0 * gains.fusion_tau))
    assert fused < 2.0 * passed
    # the F/T fed back directly: its filtered noise, K_f / (1 + K_f) of it on the cart, far above
    direct_floor = math.sqrt(3.0) * sigma * math.sqrt(dt / (2.0 * FT_ONLY.force_filter_tau)) * 2.0 / 3.0
    assert direct > 0.5 * direct_floor > 2.0 * passed


def test_force_loop_cancels_the_arms_own_dynamics_when_the_base_moves(setup):
    quiet = MeasurementNoise()
    gains = LOOP
    # the first 0.1 s: the base servo's start (the commanded speed steps up each period)
    err = _push(_held_cart_plant(setup, gains, quiet), 0.5, 0.6)[10:, 0]
    open_err = _push(_held_cart_plant(setup, replace(gains, force_feedback=0.0), quiet), 0.5, 0.6)[10:, 0]
    open_loop = np.mean(np.abs(open_err))
    # open loop the arm's links, accelerating as the arm folds, take newtons from the forward push
    assert gains.passive_feedforward and open_loop > 0.1 * PUSH[0]
    # the proportional loop divides that by 1 + K_f
    k_f, k_i = gains.force_feedback, gains.force_integral
    assert np.mean(np.abs(err[:20])) < open_loop / (1.0 + k_f)
    # the open-loop error grows as the fold speeds up (measured: -6.8 N/s); on a ramp of slope r the PI loop's error
    # settles at r / (K_f K_i) (-0.45 N), reached as 1 - exp(-K_i K_f t / (1 + K_f)) (0.85 after 0.5 s)
    slope = np.polyfit(np.arange(20, open_err.size) * plant_dt(), open_err[20:], 1)[0]
    assert slope < -1.0
    settled = np.mean(err[-10:]) / (slope / (k_f * k_i))
    assert 0.5 < settled < 1.0, settled
    # the F/T fed back directly with no integral keeps the proportional loop's share
    direct = _push(_held_cart_plant(setup, FT_ONLY, quiet), 0.5, 0.6)[30:, 0]
    assert np.mean(np.abs(direct)) > 0.5 * open_loop / (1.0 + k_f)


def plant_dt() -> float:
    """Return the plant's control period (s): one row of `_push` per period."""
    return MujocoPlantConfig().control_dt


def _law_inertia() -> np.ndarray:
    A = np.random.default_rng(7).normal(size=(7, 7))
    return A @ A.T + 7 * np.eye(7)


def _law(gains: TorqueArmGains, limit: float = 1e6):
    from wholebody.push.arm_control import TorqueArmLaw

    J = np.random.default_rng(2).normal(size=(6, 7))
    # the joint side alone (ft_noise None): a joint torque sensor's noise scales with its range, and these limits
    # stand for "no limit" (with them the fused estimate would be the F/T's; test_arm_control tests the fusion)
    law = TorqueArmLaw(np.full(7, limit), replace(gains, stiffness=0.0, damping=0.0, ft_noise=None), 0.002)
    w = np.array([20.0, -4.0, 2.0, 0.0, 0.0, 1.0])
    law.begin(w, np.zeros(7), np.zeros(7), np.zeros(7), J, _law_inertia(), t_end=0.01, dt=0.01)
    return law, J, w


def _loop_wrench(law, J, reading, steps: int) -> np.ndarray:
    """Return the loop's task-space wrench after `steps` physics steps with a constant reading (bias 0)."""
    z = np.zeros(7)
    for _ in range(steps):
        tau = law.torque(0.0, z, z, z, wrench_measured=reading)
    return np.linalg.lstsq(J.T, tau, rcond=None)[0]


def test_integral_grows_with_the_shortfall_and_holds_while_the_torques_saturate():
    gains = replace(LOOP, fusion_tau=0.0, budget=False)  # the clipped law: the budget never saturates a joint
    k = np.r_[np.full(3, gains.force_feedback), np.full(3, gains.moment_feedback)]
    law, J, w = _law(gains)
    out = _loop_wrench(law, J, 0.5 * w, 500)  # 1 s of a hand delivering half the wrench
    # feed-forward w + K (e + K_i * 1 s * e), e = w / 2
    np.testing.assert_allclose(out, w + k * (0.5 * w) * (1.0 + gains.force_integral * 1.0), rtol=1e-2, atol=1e-6)
    tight, J, w = _law(gains, limit=1e-3)  # every step saturates: the integral stops after the first
    _loop_wrench(tight, J, 0.5 * w, 500)
    assert tight.saturated_steps == 500
    np.testing.assert_allclose(tight._integral, 0.002 * 0.5 * w)


def test_fused_wrench_is_the_joint_estimate_with_the_ft_slow_part():
    gains = replace(LOOP, force_integral=0.0, fusion_tau=0.5)
    law, J, w = _law(gains)
    truth = 0.5 * w
    tau_ext = -J.T @ truth  # the cart pushes back on the hand
    rng = np.random.default_rng(3)
    sigma, bias = 3.0, np.array([2.0, 0.0, -2.0, 0.0, 2.0, 0.0])  # F/T noise, and an offset the joint side lacks
    seen = []
    for _ in range(10500):  # 21 s = 42 fusion time constants: the noise's std is measured within 15 %
        law.joint_torque_sample(tau_ext)
        seen.append(law._measured_wrench(truth + bias + rng.normal(0.0, sigma, 6)))
    seen = np.array(seen)[500:]
    # the slow part of the F/T carries its offset; its noise passes as a first-order filter's: sigma sqrt(dt / 2T)
    passed = sigma * math.sqrt(0.002 / (2.0 * gains.fusion_tau))
    np.testing.assert_allclose(seen.mean(axis=0), truth + bias, atol=3.0 * passed)
    assert np.std(seen, axis=0) == pytest.approx(np.full(6, passed), rel=0.35)


def test_fusion_starts_from_the_running_mean_of_the_readings():
    # a joint torque sensor's offset (the engine is exact; `JointTorqueNoise` adds one): the F/T's slow part must
    # take it out from the first samples on, not only after a few fusion time constants
    gains = replace(LOOP, force_integral=0.0)
    law, J, w = _law(gains)
    truth = 0.5 * w
    offset = np.array([5.0, -3.0, 2.0, 0.5, 0.0, -0.5])  # the joint side's error, as a hand wrench
    rng = np.random.default_rng(4)
    diffs = []
    for _ in range(50):  # 0.1 s, a fifth of fusion_tau
        law.joint_torque_sample(-J.T @ (truth + offset))
        ft = truth + rng.normal(0.0, 3.0, 6)
        diffs.append(ft - (truth + offset))
        seen = law._measured_wrench(ft)
    # the fused wrench is the joint estimate plus the mean of the F/T's differences so far: the offset is gone
    # within the F/T's noise over 50 samples (3 / sqrt(50) = 0.42 N per axis)
    np.testing.assert_allclose(seen, truth + offset + np.mean(diffs, axis=0), atol=1e-9)
    assert np.abs(seen - truth).max() < 2.0
    # a first-order filter from zero would still carry most of the offset: (1 - dt / T)^50 = 0.82 of it


def test_weighted_joint_estimate_is_exact_and_passes_less_sensor_noise():
    from wholebody.push.arm_control import wrench_estimator

    rng = np.random.default_rng(5)
    J = rng.normal(size=(6, 7)) * np.r_[1.0, 1.0, 0.6, 0.6, 0.3, 0.1, 0.1]  # a wrist's short lever arms
    limit = np.array([320.0, 320.0, 176.0, 176.0, 110.0, 40.0, 40.0])  # the iiwa 14's
    w = np.array([20.0, -4.0, 2.0, 0.5, 0.0, 1.0])
    for E in (wrench_estimator(J), wrench_estimator(J, limit)):
        np.testing.assert_allclose(E @ (J.T @ w), w, atol=1e-6)
    # noise in proportion to each joint's range: the weighted least squares is the minimum-variance estimate
    cov = np.diag((1e-3 * limit) ** 2)
    plain, weighted = (np.trace(E @ cov @ E.T) for E in (wrench_estimator(J), wrench_estimator(J, limit)))
    assert weighted < 0.9 * plain


def test_plan_term_acts_in_the_hands_null_space_only():
    from wholebody.push.arm_control import null_space_projector_T

    plan = np.random.default_rng(6).normal(size=7) * 5.0  # the command's planned inertial torque beyond J^T w
    taus = {}
    for in_null in (True, False):
        law, J, w = _law(TorqueArmGains(feedforward="refreshed", plan_null_space=in_null, force_feedback=0.0))
        z = np.zeros(7)
        M = _law_inertia()
        law.begin(w, J.T @ w + plan, z, z, J, M, t_end=0.01, dt=0.01)  # bias forces zero here
        taus[in_null] = law.torque(0.0, z, z, z)

    def hand_force(tau):  # the held hand's force from joint torques: (J M^-1 J^T)^-1 J M^-1 tau
        return np.linalg.solve(J @ np.linalg.solve(M, J.T), J @ np.linalg.solve(M, tau))

    # in the null space the hand feels J^T w only; in full, the plan's task-space part on top
    np.testing.assert_allclose(taus[True], J.T @ w + null_space_projector_T(J, M) @ plan, atol=1e-9)
    np.testing.assert_allclose(hand_force(taus[True]), w, atol=1e-6)
    assert np.abs(hand_force(taus[False]) - w).max() > 0.1


@pytest.mark.parametrize("space", ["joint", "hand"])
def test_joint_space_fusion_keeps_a_joint_torque_offset_out_as_the_arm_moves(space):
    gains = TorqueArmGains(fusion_space=space, force_integral=0.0)
    law, J, w = _law(gains)
    offset = np.array([3.0, -2.0, 1.0, 0.5, -0.5, 0.2, 0.1])  # each joint torque sensor's zero error (N m)
    truth = 0.5 * w
    for _ in range(500):  # 1 s = 2 fusion time constants at this posture, exact F/T
        law.joint_torque_sample(-J.T @ truth + offset)
        law._measured_wrench(truth)
    # the arm moves on (another Jacobian): the joint offset maps to another hand wrench
    J2 = J + 0.3 * np.random.default_rng(8).normal(size=J.shape)
    z = np.zeros(7)
    law.begin(w, z, z, z, J2, _law_inertia(), t_end=0.02, dt=0.01)
    law.joint_torque_sample(-J2.T @ truth + offset)
    seen = law._measured_wrench(truth)
    moved = np.abs(seen - truth).max()
    if space == "joint":  # the offsets were learnt per joint: none left
        assert moved < 1e-6
    else:  # what the hand-space correction learnt at the old posture no longer fits
        assert moved > 0.1


def _yaw(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize(("space", "frame"), [("joint", "world"), ("hand", "mount"), ("hand", "world")])
def test_fusion_keeps_a_joint_torque_offset_out_as_the_base_turns(space, frame):
    """The base turns at 0.5 rad/s with the arm's posture held: the world-aligned Jacobian turns with it, and a joint
    torque offset maps to a hand wrench fixed in the arm's mount frame. Kept per joint or in that frame, the F/T's
    correction stays right; kept world-aligned it lags the turn by ``fusion_tau`` (error: rate x tau x offset)."""
    gains = TorqueArmGains(fusion_space=space, fusion_frame=frame, force_integral=0.0)
    law, J0, w = _law(gains)
    offset = np.array([3.0, -2.0, 1.0, 0.5, -0.5, 0.2, 0.1])
    truth = 0.5 * w
    z, M = np.zeros(7), _law_inertia()
    errors = []
    for k in range(1500):  # 3 s: 1 s still, then 2 s turning at 0.5 rad/s
        R = _yaw(0.5 * max(k * 0.002 - 1.0, 0.0))
        J = np.vstack([R @ J0[:3], R @ J0[3:]])
        law.begin(w, z, z, z, J, M, t_end=0.01, dt=0.01)
        law.joint_torque_sample(-J.T @ truth + offset, R)
        errors.append(np.abs(law._measured_wrench(truth) - truth).max())
    lag = max(errors[-250:])
    if frame == "world":
        assert lag > 0.1 if space == "hand" else lag < 1e-6
    else:
        assert lag < 1e-6
