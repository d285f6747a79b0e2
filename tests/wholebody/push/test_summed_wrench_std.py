"""The online estimator's wrench noise in the push loop: each F/T sensor's noise carried to {b}'s origin, summed.

The formula (`summed_wrench_std`) is checked against the noise of the wrench the controller measures on both plants:
the readings are drawn again and again at one state and carried to {b} by the controller (`_measured_gamma`).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from wholebody.push.config import PushConfig
from wholebody.push.loop import build_controller, make_estimator, sensor_origins, summed_wrench_std
from wholebody.push.plant import RobotCommand
from wholebody.push.plants import kinematic_plant
from wholebody.push.robot import cart_se3

N_DRAWS = 3000  # the sample std's relative error is about 1 / sqrt(2 N) = 1.3 %


def _measured_std(gammas: np.ndarray, theta: float) -> tuple[float, float]:
    """Return the std of (forward force, yaw torque) of measured cart wrenches (fx, fy in {s}, tau)."""
    fu = math.cos(theta) * gammas[:, 0] + math.sin(theta) * gammas[:, 1]
    return float(np.std(fu)), float(np.std(gammas[:, 2]))


def _ft_points(setup) -> np.ndarray:
    """Return the built robots' F/T frame origins (x, y) in {b} at the start (what the controller sums about)."""
    T = cart_se3(setup.q0)
    return np.array(
        [
            T.actInv(mm.wb.frame_placement(mm.x, fid)).translation[:2]
            for mm in setup.controller.robots
            for fid in mm.ft_ids
        ]
    )


@pytest.fixture(scope="module", params=[1, 2], ids=["one_hand", "two_hands"])
def case(request):
    cfg = PushConfig(trajectory=2, n_arms=request.param, duration=2.0)
    return cfg, build_controller(cfg)


def test_sensor_origins_are_the_built_robots_ft_frames(case):
    cfg, setup = case
    assert sensor_origins(cfg) == pytest.approx(_ft_points(setup), abs=1e-3)


def test_the_formula_is_the_sum_over_the_sensors():
    cfg = PushConfig(trajectory=1)
    sf, st = cfg.noise.force, cfg.noise.torque
    pts = np.array([[-0.3, -0.2], [-0.3, 0.1]])
    f, t = summed_wrench_std(cfg, pts)
    assert f == pytest.approx(math.sqrt(2.0) * sf)
    assert t == pytest.approx(math.sqrt(2.0 * st * st + (0.09 + 0.04 + 0.09 + 0.01) * sf * sf))
    assert summed_wrench_std(cfg, pts[:1]) == pytest.approx((sf, math.sqrt(st * st + 0.13 * sf * sf)))
    est = make_estimator(cfg, np.zeros(3))
    assert est.options.wrench_std == summed_wrench_std(cfg)  # type: ignore[attr-defined]


def test_kinematic_plant_noise_is_the_formulas(case):
    """The kinematic plant's readings of zero hand wrenches are their noise alone: the cart stays at rest."""
    cfg, setup = case
    plant = kinematic_plant(cfg, setup)
    ctrl = setup.controller
    cmds = [
        RobotCommand(
            arm_velocity=np.zeros(mm.wb.n_arm),
            arm_position=x[3 : 3 + mm.wb.n_arm].copy(),
            arm_torque=np.zeros(mm.wb.n_arm),
            base_twist=np.zeros(3),
            wheel_rates=np.zeros(4),
            hand_wrench=np.zeros((mm.n_hands, 6)) if mm.n_hands > 1 else np.zeros(6),
        )
        for mm, x in zip(ctrl.robots, setup.robot_x0)
    ]
    gammas = []
    for _ in range(N_DRAWS):
        plant.step(cmds)
        gammas.append(ctrl._measured_gamma(plant.measure()))
    f, t = summed_wrench_std(cfg)
    assert _measured_std(np.array(gammas), float(setup.q0[2])) == pytest.approx((f, t), rel=0.05)


def test_mujoco_plant_noise_is_the_formulas():
    """The MuJoCo plant's F/T reading (noise at its sensor site) and motion capture drawn again at one state."""
    from wholebody.push.mujoco_plant import MujocoPlant

    cfg = PushConfig(trajectory=2, duration=2.0)
    setup = build_controller(cfg)
    plant = MujocoPlant(setup.controller.robots, setup.q0, cfg.true_params, noise=cfg.noise, seed=3)
    ctrl = setup.controller
    gammas = []
    for _ in range(N_DRAWS):
        plant._ft = [plant._ft_reading(i, noisy=True) for i in range(len(plant._ft))]
        plant._z = plant._motion_capture()
        gammas.append(ctrl._measured_gamma(plant.measure()))
    assert _measured_std(np.array(gammas), float(setup.q0[2])) == pytest.approx(summed_wrench_std(cfg), rel=0.05)
