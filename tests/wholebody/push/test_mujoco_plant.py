"""The MuJoCo plant: the scene keeps the robots' masses, gravity compensation, the F/T sensor vs the weld's force."""

from __future__ import annotations

import math
from dataclasses import replace

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from cart.simulate import MeasurementNoise
from tests.wholebody.push.mujoco_hold import hold_commands, quiet_plant
from wholebody.push import PushConfig, build_controller
from wholebody.push.arm_control import TorqueArmGains, null_space_projector_T
from wholebody.push.config import TRUE_CART
from wholebody.push.mujoco_plant import JointTorqueNoise, MujocoPlant, MujocoPlantConfig, MujocoPlantError
from wholebody.push.plant import RobotCommand

CONFIG = PushConfig(trajectory=2, duration=2.0, contact="fixed")
QUIET = MeasurementNoise()  # no noise


@pytest.fixture(scope="module")
def setup():
    return build_controller(CONFIG)


def _plant(setup, **kw) -> MujocoPlant:
    return quiet_plant(setup, **kw)


def _hold(plant: MujocoPlant, wrench=np.zeros(6), arm_torque=None) -> RobotCommand:
    """A command that holds the arm where it is and the base still, with `wrench` allocated to the hand."""
    return hold_commands(plant, wrench, arm_torque)[0]


def test_scene_keeps_the_robots_mass_and_the_carts_inertial(setup):
    plant = _plant(setup, noise=QUIET)
    m = plant.scene.model
    r = plant.scene.robots[0]
    # MuJoCo's URDF import would fuse the fixed links into the world (36 kg) and give links without <inertial>
    # the mass of their geoms (267 kg): the scene keeps the URDF's masses, Pinocchio's 226.853 kg
    total = pin.computeTotalMass(setup.controller.robots[0].wb.robot.model)
    assert m.body_subtreemass[r.root_body] == pytest.approx(total, rel=1e-9) and total == pytest.approx(226.853)
    ci = plant.cart_inertial()
    assert ci.mass == pytest.approx(TRUE_CART.m, rel=1e-9)
    assert ci.com_b == pytest.approx((TRUE_CART.dx, TRUE_CART.dy), abs=2e-3)  # settled: casters trail
    assert ci.inertia == pytest.approx(TRUE_CART.I, rel=1e-3)
    # four solid-cylinder wheels of 0.35 kg: each adds J / r^2 = m / 2 to the forward mass
    assert ci.mass_effective == pytest.approx(TRUE_CART.m + 4 * 0.35 / 2, rel=1e-3)


def test_pinocchio_gravity_equals_mujocos_bias_forces(setup):
    plant = _plant(setup, noise=QUIET)
    mm, r, d = setup.controller.robots[0], plant.scene.robots[0], plant.scene.data
    d.qvel[:] = 0.0  # at rest the bias forces are gravity alone
    mujoco.mj_forward(plant.scene.model, d)
    x = plant.robot_states()[0]
    g = pin.computeGeneralizedGravity(mm.model, mm.data, mm.wb.to_pinocchio_q(x))[mm.wb.arm_idx_v]
    np.testing.assert_allclose(g, d.qfrc_bias[r.arm_dof], atol=1e-9 * np.abs(g).max())


def _released(setup, arm_torque_of) -> float:
    """Return the largest arm joint motion (rad) over 1 s with the grasp released and torques `arm_torque_of(x)`."""
    gains = TorqueArmGains(stiffness=0.0, damping=0.0, feedforward="command")
    exact = JointTorqueNoise(0.0, 0.0)  # the force loop in free space would move the arm with the sensing's noise
    plant = _plant(setup, noise=QUIET, config=MujocoPlantConfig(torque_gains=gains, joint_torque_noise=exact))
    r = plant.scene.robots[0]
    plant.scene.data.eq_active[r.weld] = 0  # the hand lets go of the handle
    q0 = plant.measure().robots[0].q_arm.copy()
    worst = 0.0
    for _ in range(100):
        x = plant.robot_states()[0]
        cmd = replace(_hold(plant), arm_torque=arm_torque_of(x))
        plant.step([cmd])
        worst = max(worst, float(np.abs(plant.measure().robots[0].q_arm - q0).max()))
    return worst


def test_gravity_compensation_holds_an_arm_still_with_no_command(setup):
    mm = setup.controller.robots[0]

    def gravity(x):  # Pinocchio's gravity torques at the measured joints: nothing else commanded
        return pin.computeGeneralizedGravity(mm.model, mm.data, mm.wb.to_pinocchio_q(x))[mm.wb.arm_idx_v]

    assert _released(setup, gravity) < 2e-3
    assert _released(setup, lambda x: np.zeros(7)) > 0.1  # without it the arm falls


def _weld_wrench_on_cart(plant: MujocoPlant) -> np.ndarray:
    """Return the weld's constraint wrench on the cart: world force and torque about the cart body's origin."""
    m, d = plant.scene.model, plant.scene.data
    r = plant.scene.robots[0]
    rows = (d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & (d.efc_id == r.weld)
    assert rows.sum() == 6
    qfrc = np.zeros(m.nv)
    mujoco.mj_mulJacTVec(m, d, qfrc, np.where(rows, d.efc_force, 0.0))
    c = plant.scene.cart_dof
    R = d.xmat[plant.scene.cart_body].reshape(3, 3)
    return np.r_[qfrc[c : c + 3], R @ qfrc[c + 3 : c + 6]]  # free joint: world force, body-frame torque


def test_ft_sensor_equals_the_grasps_constraint_force_within_noise(setup):
    noise = MeasurementNoise(force=3.0, torque=0.3)
    # the arm's own gravity compensation (the plant's bias forces) + J^T w of the allocated push, no F/T loop (its
    # reaction to the sensor's noise shakes the gripper, whose inertia is beyond the sensor)
    config = MujocoPlantConfig(torque_gains=TorqueArmGains(feedforward="bias", force_feedback=0.0))
    plant = _plant(setup, noise=noise, seed=3, config=config)
    push = np.array([25.0, -8.0, 0.0, 0.0, 0.0, 1.5])  # world-aligned at the grasp, on the cart
    errors_noisy, errors_clean = [], []
    for _ in range(40):
        plant.step([_hold(plant, push)])
        d, r = plant.scene.data, plant.scene.robots[0]
        mujoco.mj_forward(plant.scene.model, d)  # constraint forces of the current state
        weld = _weld_wrench_on_cart(plant)
        o = d.xpos[plant.scene.cart_body]
        p = d.site_xpos[r.hand_site]
        clean = plant._hand_wrench_world(0, plant._sensor_wrench(0))
        noisy = plant._hand_wrench_world(0, plant.measure().robots[0].ft)
        for w, out in ((clean, errors_clean), (noisy, errors_noisy)):
            on_cart = np.r_[w[:3], w[3:] + np.cross(p - o, w[:3])]  # the hand's wrench about the cart origin
            out.append(on_cart - weld)
    e_clean, e_noisy = np.array(errors_clean), np.array(errors_noisy)
    # the sensor is the weld's force: the reading removes the load (weight and inertia) of the 0.9 kg of gripper
    # beyond it, which without its inertia leaves 0.8 N and 0.8 N m here
    assert np.abs(e_clean[:, :3]).max() < 0.01
    assert np.abs(e_clean[:, 3:]).max() < 0.05
    # and the reading adds the sensor's white noise: 3 N per axis
    assert np.std(e_noisy[:, :3]) == pytest.approx(3.0, rel=0.3)
    assert np.abs(e_noisy[:, :3].mean(axis=0)).max() < 3.0 * 4 / math.sqrt(40) + 1.0


def test_null_space_torques_put_no_force_on_a_held_hand():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(6, 7))
    A = rng.normal(size=(7, 7))
    M = A @ A.T + 7 * np.eye(7)
    NT = null_space_projector_T(J, M)
    raw = rng.normal(size=7)

    def hand_force(tau):  # the hand's force from joint torques tau with the hand held: (J M^-1 J^T)^-1 J M^-1 tau
        return np.linalg.solve(J @ np.linalg.solve(M, J.T), J @ np.linalg.solve(M, tau))

    assert np.abs(hand_force(NT @ raw)).max() < 1e-6 * np.abs(raw).max()
    assert np.abs(hand_force(raw)).max() > 0.1 * np.abs(raw).max()


def test_closed_loop_run_reports_its_diagnostics(setup):
    from wholebody.push.loop import run_loop

    fresh = build_controller(CONFIG)
    plant = MujocoPlant(fresh.controller.robots, fresh.q0, CONFIG.true_params, noise=CONFIG.noise, seed=1)
    res = run_loop(CONFIG, fresh.controller, plant)
    rep = plant.report()
    for key in (
        "cart_mass_kg",
        "cart_mass_effective_kg",
        "wrench_error_rms_n",
        "grasp_slip_max_m",
        "base_wheel_slip_max_m_s",
        "real_time_factor",
    ):
        assert key in rep
    assert rep["base_wheel_slip_max_m_s"] is None  # the Ridgeback's base is planar
    # one hand: its whole wrench error moves the cart, none of it is a squeeze between hands
    assert rep["wrench_error_internal_rms_n"] == pytest.approx(0.0, abs=1e-9)
    assert rep["wrench_error_net_rms_n"] == pytest.approx(rep["wrench_error_rms_n"], rel=1e-9)
    assert 0.0 < rep["grasp_slip_max_m"] < 5e-3
    assert rep["plant_arm_torque_limit_ratio"] < 1.0
    assert 0.0 <= rep["cart_tilt_max_deg"] < 2.0 and rep["cart_tipped_at_s"] is None  # the cart stays upright
    assert res.metrics.tracking_max_mm < 20.0
    # the cart moved along the trajectory's start (Traj. 2 accelerates from rest after 1 s)
    q, qd = plant.cart_state()
    assert qd[0] > 0.1


def test_bad_commands_are_rejected(setup):
    plant = _plant(setup, noise=QUIET)
    with pytest.raises(MujocoPlantError, match="commands for 1 robots"):
        plant.step([])
    with pytest.raises(MujocoPlantError, match="hand_wrench"):
        plant.step([replace(_hold(plant), hand_wrench=np.zeros(3))])
    with pytest.raises(MujocoPlantError, match="grasp point"):
        _plant(setup, grasp_points_b=[(-0.15, 0.1, 0.9365)])


def test_wmra_rolls_on_its_wheels_with_the_cart_in_hand():
    """Open loop: both wheels at 1 rad/s, the arm holding: the base rolls forward at ~r w without sliding sideways."""
    cfg = PushConfig(robot="wmra", contact="fixed", duration=1.0)
    wmra = build_controller(cfg)
    plant = MujocoPlant(wmra.controller.robots, wmra.q0, TRUE_CART, noise=QUIET)
    r = plant.scene.robots[0]
    assert r.base == "differential" and r.wheel_radius == pytest.approx(0.17)
    x0 = plant.robot_states()[0]
    twists = []
    for _ in range(100):
        m = plant.measure().robots[0]
        n = m.q_arm.size
        cmd = RobotCommand(
            arm_velocity=np.zeros(n),
            arm_position=m.q_arm.copy(),
            arm_torque=np.zeros(n),
            base_twist=np.array([0.17, 0.0, 0.0]),
            wheel_rates=np.array([1.0, 1.0]),
            hand_wrench=np.zeros(6),
        )
        plant.step([cmd])
        twists.append(plant.measure().robots[0].base_twist)
    tw = np.array(twists[50:])
    assert tw[:, 0].mean() == pytest.approx(0.17, rel=0.1)  # rolling: v = r w
    assert np.abs(tw[:, 1]).max() < 0.05 * tw[:, 0].mean()  # the nonholonomic constraint, physically
    x1 = plant.robot_states()[0]
    assert x1[0] - x0[0] == pytest.approx(0.17 * 0.8, rel=0.25)
    rep = plant.report()
    assert 0.0 < rep["base_wheel_slip_max_m_s"] < 0.1  # the step to 1 rad/s spins the wheels up with some slip


def test_ft_force_loop_adds_the_wrench_error_through_the_jacobian():
    """The torque law's F/T loop: J^T K_f (w - w_f), w_f the low-passed reading; nothing when the reading is w."""
    from wholebody.push.arm_control import TorqueArmLaw

    rng = np.random.default_rng(1)
    J = rng.normal(size=(6, 7))
    A = rng.normal(size=(7, 7))
    M = A @ A.T + 7 * np.eye(7)
    w = np.array([30.0, -5.0, 0.0, 0.0, 0.0, 2.0])
    q = np.zeros(7)

    def torques(k_f, reading, steps=50):
        gains = TorqueArmGains(
            stiffness=0.0, damping=0.0, force_feedback=k_f, moment_feedback=k_f, force_integral=0.0, fusion_tau=0.0
        )
        law = TorqueArmLaw(np.full(7, 1e6), gains, 0.002)
        law.begin(w, J.T @ w, q, q, J, M, t_end=0.01, dt=0.01)
        taus = [law.torque(0.0, q, q, np.zeros(7), wrench_measured=reading) for _ in range(steps)]
        return taus[0], taus[-1]

    _, open_loop = torques(0.0, np.zeros(6))
    np.testing.assert_allclose(open_loop, J.T @ w)  # off: the feed-forward alone
    _, matched = torques(2.0, w)
    np.testing.assert_allclose(matched, J.T @ w, atol=1e-9)  # the hand pushes as asked: no correction
    first, settled = torques(2.0, 0.5 * w)  # the hand delivers half: the loop adds K_f times the shortfall
    np.testing.assert_allclose(first, J.T @ w + J.T @ (2.0 * 0.5 * w), atol=1e-9)  # the filter starts at the reading
    np.testing.assert_allclose(settled, J.T @ (2.0 * w), atol=1e-9)


def _base_lag(setup, integral: float) -> float:
    """Return how far (m) the base falls behind the integral of its commanded forward speed over a 1 m/s^2 ramp."""
    from wholebody.push.mujoco_scene import ServoGains

    plant = _plant(setup, noise=QUIET, config=MujocoPlantConfig(servos=ServoGains(base_integral=integral)))
    x0, travelled = plant.robot_states()[0][0], 0.0
    for k in range(40):
        v = 0.01 * (k + 1)  # 0.4 s at 1 m/s^2
        plant.step([replace(_hold(plant), base_twist=np.array([v, 0.0, 0.0]))])
        travelled += 0.01 * v
    return travelled - (plant.robot_states()[0][0] - x0)


def test_base_wheel_loop_integral_keeps_the_base_on_its_commanded_path(setup):
    lag_p = _base_lag(setup, 0.0)
    lag_pi = _base_lag(setup, 10.0)
    assert lag_p > 0.005  # a velocity servo lags by acceleration / bandwidth, and that adds up over the ramp
    assert abs(lag_pi) < 0.5 * lag_p


def test_plant_report_keeps_the_controllers_torque_ratio(setup):
    """The plant's torque ratio has its own key: merged into `push --json` it cannot overwrite the controller's."""
    fresh = build_controller(CONFIG)
    plant = MujocoPlant(fresh.controller.robots, fresh.q0, CONFIG.true_params, noise=CONFIG.noise, seed=CONFIG.seed)
    rep = plant.report()
    assert "plant_arm_torque_limit_ratio" in rep and "arm_torque_limit_ratio" not in rep
