"""Tests of wholebody.motion.kinematics: WMRA closed forms (paper eq. 1-21) and finite differences of the FK."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import robots
from robots.wmra import WMRA_D, WMRA_MOUNT, WMRA_TRACK, WMRA_WHEEL_RADIUS
from studies import wmra_closed_form as cf
from wholebody.motion.kinematics import wholebody_for


@pytest.fixture(scope="module")
def wmra():
    return wholebody_for(robots.load("wmra"))


def _random_x(wb, rng):
    return np.r_[rng.uniform(-3, 3, 2), rng.uniform(-np.pi, np.pi), rng.uniform(wb.arm_lower, wb.arm_upper)]


def test_wmra_fk_equals_dh_product(wmra):
    rng = np.random.default_rng(10)
    for _ in range(20):
        x = _random_x(wmra, rng)
        T = cf.ground_to_ee(x[:3], x[3:], WMRA_D, WMRA_MOUNT, WMRA_WHEEL_RADIUS)  # eq. (13)
        np.testing.assert_allclose(wmra.ee_placement(x).homogeneous, T, atol=1e-12)
        # arm alone, frame A -> EE (eq. 2)
        oMa = wmra.frame_placement(x, "arm_base")
        np.testing.assert_allclose(
            (oMa.inverse() * wmra.ee_placement(x)).homogeneous, cf.arm_fk(x[3:], WMRA_D), atol=1e-12
        )


def test_wmra_combined_jacobian_equals_paper_closed_form(wmra):
    rng = np.random.default_rng(11)
    for _ in range(50):
        x = _random_x(wmra, rng)
        J = wmra.combined_jacobian(x)
        J_paper = cf.combined_jacobian(x[:3], x[3:], WMRA_D, WMRA_TRACK, WMRA_MOUNT, WMRA_WHEEL_RADIUS)
        assert J.shape == (6, 9)
        np.testing.assert_allclose(J, J_paper, atol=1e-9)


def test_paper_arm_jacobian_is_the_derivative_of_eq_2():
    """The closed-form J_E itself (eq. 3) against central differences of the D-H product."""
    rng = np.random.default_rng(12)
    q = rng.uniform(-2, 2, 7)
    J = cf.arm_jacobian(q, WMRA_D)
    eps = 1e-6
    for i in range(7):
        dq = np.zeros(7)
        dq[i] = eps
        Tp, Tm = cf.arm_fk(q + dq, WMRA_D), cf.arm_fk(q - dq, WMRA_D)
        np.testing.assert_allclose((Tp[:3, 3] - Tm[:3, 3]) / (2 * eps), J[:3, i], atol=1e-8)
        np.testing.assert_allclose(pin.log3(Tp[:3, :3] @ Tm[:3, :3].T) / (2 * eps), J[3:, i], atol=1e-8)


def _fd_twist(wb, x, u, eps=1e-6):
    Tp = wb.ee_placement(wb.integrate(x, u, eps))
    Tm = wb.ee_placement(wb.integrate(x, u, -eps))
    return np.r_[(Tp.translation - Tm.translation) / (2 * eps), pin.log3(Tp.rotation @ Tm.rotation.T) / (2 * eps)]


@pytest.mark.parametrize(
    "name,base_input", [("wmra", "wheels"), ("ridgeback_iiwa", "wheels"), ("ridgeback_iiwa", "twist")]
)
def test_combined_jacobian_matches_finite_differences(name, base_input):
    wb = wholebody_for(robots.load(name), base_input)
    rng = np.random.default_rng(13)
    for _ in range(10):
        x = _random_x(wb, rng)
        J = wb.combined_jacobian(x)
        for k in range(wb.n_u):  # column by column: each input alone
            u = np.zeros(wb.n_u)
            u[k] = 1.0
            np.testing.assert_allclose(J[:, k], _fd_twist(wb, x, u), atol=1e-7)


def test_integrate_moves_wheels_by_exact_odometry(wmra):
    x = np.r_[0.5, 0.2, 0.3, np.zeros(7)]
    u = np.r_[np.zeros(7), 0.4, 0.9]
    new = wmra.integrate(x, u, 0.5)
    np.testing.assert_allclose(new[:3], wmra.base.integrate(x[:3], u[7:] * 0.5), atol=1e-15)
    T = cf.ground_to_wheelchair(*x[:3], WMRA_WHEEL_RADIUS) @ cf.odometry_step(0.2, 0.45, WMRA_TRACK, WMRA_WHEEL_RADIUS)
    np.testing.assert_allclose(new[:2], T[:2, 3], atol=1e-12)


def test_to_pinocchio_q_sets_wheels_and_root(wmra):
    x = np.r_[1.0, 2.0, 0.5, np.arange(7) * 0.1]
    q = wmra.to_pinocchio_q(x, wheel_angles=[0.3, -0.7])
    assert q.shape == (wmra.model.nq,)
    j = wmra.model.joints[wmra.model.getJointId("wheel_right_joint")]
    assert q[j.idx_q] == pytest.approx(np.cos(-0.7)) and q[j.idx_q + 1] == pytest.approx(np.sin(-0.7))
    j = wmra.model.joints[wmra.model.getJointId("arm_joint4")]
    assert q[j.idx_q] == pytest.approx(0.3)
    pin.framesForwardKinematics(wmra.model, wmra.data, q)
    base = wmra.data.oMf[wmra.robot.frame_id("base")]
    np.testing.assert_allclose(base.translation, [1.0, 2.0, WMRA_WHEEL_RADIUS], atol=1e-12)
