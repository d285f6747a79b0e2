"""Several hands on one rigid cart: the stacked hand wrench error splits into the cart's net wrench and the squeeze.

``G = [G_1 ... G_n]`` maps the hands' wrenches to the net wrench on the cart (paper eqs. 23-25, spatial form);
``P = G^+ G`` keeps the part that moves the cart and ``I - P`` the internal wrench between the hands, which no cart
motion shows (the part two integrating loops could drift along).
"""

from __future__ import annotations

import numpy as np
import pytest

from wholebody.push.arm_control import TorqueArmGains, TorqueArmLaw, net_wrench_projector
from wholebody.push.mujoco_plant import MujocoPlantConfig, MujocoPlantError

GRASPS = np.array([[0.6, -0.2, 0.9], [0.6, 0.2, 0.9]])  # two hands on a handle bar, world frame


def _net_map(points: np.ndarray) -> np.ndarray:
    """The net wrench about the world origin of stacked hand wrenches [f; n] at `points` (6 x 6n)."""
    G = np.zeros((6, 6 * len(points)))
    for i, p in enumerate(points):
        G[:, 6 * i : 6 * i + 6] = np.eye(6)
        G[3:, 6 * i : 6 * i + 3] = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
    return G


def test_one_hand_keeps_all_of_its_error():
    assert np.allclose(net_wrench_projector(GRASPS[:1]), np.eye(6))


def test_squeeze_and_twist_between_two_hands_are_internal():
    P = net_wrench_projector(GRASPS)
    axis = (GRASPS[1] - GRASPS[0]) / np.linalg.norm(GRASPS[1] - GRASPS[0])
    squeeze = np.r_[5.0 * axis, 0, 0, 0, -5.0 * axis, 0, 0, 0]  # the hands press toward each other
    twist = np.r_[0, 0, 0, 2.0 * axis, 0, 0, 0, -2.0 * axis]  # opposite moments about the bar
    assert np.allclose(P @ squeeze, 0.0, atol=1e-12)
    assert np.allclose(P @ twist, 0.0, atol=1e-12)
    push = np.r_[10.0, 0, -5, 0, 0, 0, 10.0, 0, -5, 0, 0, 0]  # both hands push forward and down alike
    assert np.allclose(P @ push, push)


def test_projection_keeps_the_net_wrench_and_removes_only_internal_wrench():
    rng = np.random.default_rng(3)
    points = GRASPS + rng.normal(0.0, 0.1, GRASPS.shape)
    P = net_wrench_projector(points)
    G = _net_map(points)
    e = rng.normal(0.0, 5.0, 12)
    assert np.allclose(G @ (P @ e), G @ e)  # the cart feels the same net wrench
    assert np.allclose(G @ (e - P @ e), 0.0, atol=1e-9)  # what is removed moves nothing
    assert np.allclose(P @ P, P) and np.allclose(P, P.T)  # an orthogonal projector
    # the same split about any reference point: the net wrench's moment point does not matter
    assert np.allclose(net_wrench_projector(points + np.array([3.0, -1.0, 0.5])), P)


def test_loop_integrates_only_the_error_it_is_given():
    gains = TorqueArmGains(force_feedback=2.0, moment_feedback=1.0, force_integral=5.0)
    law = TorqueArmLaw(np.full(7, 100.0), gains, physics_dt=0.002)
    e = np.r_[3.0, 0, 0, 0, 0, 0]
    net = np.r_[1.0, 0, 0, 0, 0, 0]
    for _ in range(100):
        u = law.force_loop(e, net)
    # proportional on the whole error, integral on the part given: 2 (3 + 5 * 100 * 0.002 * 1)
    assert u[0] == pytest.approx(2.0 * (3.0 + 5.0 * 0.2 * 1.0))


def test_multi_arm_force_loop_mode_is_checked():
    with pytest.raises(MujocoPlantError, match="multi_arm_force_loop"):
        MujocoPlantConfig(multi_arm_force_loop="squeeze")
