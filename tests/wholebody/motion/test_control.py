"""Tests of wholebody.motion.control: the resolved-rate QP, its limits, the safety band, degenerate targets."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import robots
from wholebody.motion.control import (
    ControllerConfig,
    ResolvedRateController,
    SafetyBand,
    manipulability,
    manipulability_gradient,
    pose_error,
)
from wholebody.errors import WholeBodyError
from wholebody.motion.experiments import initial_state
from wholebody.motion.kinematics import wholebody_for

DT = 0.01


@pytest.fixture(scope="module")
def wmra():
    return wholebody_for(robots.load("wmra"))


def test_unconstrained_step_equals_damped_least_squares(wmra):
    """Inactive limits: the QP's optimum is the closed-form weighted damped least squares."""
    x = initial_state(wmra)
    cfg = ControllerConfig(secondary="none", damping=1e-4, gain=5.0)
    ctrl = ResolvedRateController(wmra, cfg)
    T = wmra.ee_placement(x)
    T_des = pin.SE3(T.rotation, T.translation + [0.002, -0.001, 0.001])
    v_des = np.array([0.05, 0.0, 0.01, 0.0, 0.0, 0.02])
    res = ctrl.step(x, T_des, v_des, DT)
    J = wmra.combined_jacobian(x)
    v_ref = v_des + 5.0 * pose_error(T, T_des)
    u_ls = np.linalg.solve(J.T @ J + 1e-4 * np.eye(9), J.T @ v_ref)
    np.testing.assert_allclose(res.u, u_ls, atol=1e-5)  # proxqp tolerance
    assert res.solver_ok and not res.singular


def test_position_limit_is_not_crossed(wmra):
    x = initial_state(wmra)
    x[3 + 5] = wmra.arm_upper[5] - 1e-3  # joint 6 just below its limit
    ctrl = ResolvedRateController(wmra, ControllerConfig(secondary="none"))
    T = wmra.ee_placement(x)
    # ask for the twist that joint 6 alone would produce moving up fast: the QP must stop at the limit
    J = wmra.combined_jacobian(x)
    res = ctrl.step(x, T, J[:, 5] * 0.9, DT)
    x1 = wmra.integrate(x, res.u, DT)
    assert x1[3 + 5] <= wmra.arm_upper[5] + 1e-12
    assert res.u[5] <= (wmra.arm_upper[5] - x[3 + 5]) / DT + 1e-12
    assert np.all(np.abs(res.u[:7]) <= wmra.arm_velocity_limit + 1e-12)
    assert np.all(np.abs(res.u[7:]) <= wmra.wheel_velocity_limit + 1e-12)


@pytest.mark.parametrize("offset", [[0.0, 0.0, 5.0], [50.0, -20.0, 0.0]])
def test_unreachable_target_is_bounded_and_flagged(wmra, offset):
    x = initial_state(wmra)
    ctrl = ResolvedRateController(wmra)
    T = wmra.ee_placement(x)
    T_des = pin.SE3(pin.exp3(np.array([2.0, -1.0, 0.5])) @ T.rotation, T.translation + offset)
    for _ in range(50):
        res = ctrl.step(x, T_des, None, DT)
        assert np.all(np.isfinite(res.u))
        assert np.all(np.abs(res.u[:7]) <= wmra.arm_velocity_limit + 1e-12)
        assert np.all(np.abs(res.u[7:]) <= wmra.wheel_velocity_limit + 1e-12)
        x = wmra.integrate(x, res.u, DT)
        assert np.all(x[3:] >= wmra.arm_lower - 1e-12) and np.all(x[3:] <= wmra.arm_upper + 1e-12)
    assert res.saturated


def test_singular_configuration_is_flagged_not_nan(wmra):
    x = np.r_[0.0, 0.0, 0.0, np.zeros(7)]  # arm stretched: wrist axes aligned
    ctrl = ResolvedRateController(wmra, ControllerConfig(singular_threshold=1e-6))
    J = wmra.combined_jacobian(x)
    smin = np.linalg.svd(J, compute_uv=False)[-1]
    T = wmra.ee_placement(x)
    res = ctrl.step(x, T, np.ones(6), DT)
    assert np.all(np.isfinite(res.u))
    assert res.sigma_min == pytest.approx(smin)
    assert res.singular == (smin < 1e-6)


def test_safety_band_constraint_holds_and_is_feasible(wmra):
    """The base's look-ahead point stays in its polygon even when the target pulls far outside."""
    band = SafetyBand(0.3)
    ctrl = ResolvedRateController(wmra, band=band)
    x = initial_state(wmra)
    T = wmra.ee_placement(x)
    T_des = pin.SE3(T.rotation, T.translation + [2.0, 1.0, 0.0])  # pulls the base out of the band
    ell = band.lookahead_for(False)
    for _ in range(400):
        res = ctrl.step(x, T_des, None, DT, band_center=(0.0, 0.0))
        x = wmra.integrate(x, res.u, DT)
        assert res.solver_ok
        assert np.linalg.norm(x[:2]) <= band.radius + 1e-6
        P = x[:2] + ell * np.array([np.cos(x[2]), np.sin(x[2])])
        assert np.max(band.normals() @ P) <= band.inner_radius(ell) + 1e-6
    free = ResolvedRateController(wmra)
    y = initial_state(wmra)
    for _ in range(400):
        y = wmra.integrate(y, free.step(y, T_des, None, DT).u, DT)
    assert np.linalg.norm(y[:2]) > band.radius  # without the band the base leaves the disc


def test_twist_input_respects_wheel_limits():
    rb = wholebody_for(robots.load("ridgeback_iiwa"), "twist")
    ctrl = ResolvedRateController(rb)
    x = initial_state(rb)
    T = rb.ee_placement(x)
    res = ctrl.step(x, pin.SE3(T.rotation, T.translation + [30.0, 30.0, 0.0]), None, DT)
    w = rb.wheel_rates(res.u)
    assert np.max(np.abs(w) / rb.wheel_velocity_limit) <= 1.0 + 1e-12


def test_manipulability_gradient_points_uphill(wmra):
    x = initial_state(wmra)
    g = manipulability_gradient(wmra, x)
    step = np.r_[np.zeros(3), 1e-3 * g / np.linalg.norm(g)]
    assert manipulability(wmra, x + step) > manipulability(wmra, x)


def test_bad_config_raises(wmra):
    with pytest.raises(WholeBodyError):
        ControllerConfig(secondary="nope")
    with pytest.raises(WholeBodyError):
        ControllerConfig(solver="not-a-solver")
    with pytest.raises(WholeBodyError):
        SafetyBand(-1.0)
    with pytest.raises(WholeBodyError):
        ResolvedRateController(wmra).step(initial_state(wmra), pin.SE3.Identity(), None, 0.0)
