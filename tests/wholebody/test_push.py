"""Closed-loop push (wholebody.push): end to end, torque limits, estimation on/off, sensing and torque models."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import robots
from cart import model as cart_model
from wholebody.errors import WholeBodyError
from wholebody.push import (
    PushConfig,
    SensorNoise,
    MobileManipulator,
    ft_measurement,
    ft_to_cart_gamma,
    grasp_rotation,
    grasp_target,
    run_push,
)

SHORT = dict(trajectory=1, duration=8.0)


@pytest.fixture(scope="module")
def runs():
    """One short Traj. 1 run with estimation and one with the estimator off (wrong initial mass 16 kg vs 20 kg)."""
    on = run_push(PushConfig(estimation=True, contact="fixed", fixed_contact_y=(0.0,), **SHORT))
    off = run_push(PushConfig(estimation=False, contact="fixed", fixed_contact_y=(0.0,), **SHORT))
    return on, off


def test_closed_loop_follows_short_trajectory_within_torque_limits(runs):
    on, _ = runs
    m = on.metrics
    travelled = np.hypot(*(on.q_desired[-1, :2] - on.q_desired[0, :2]))
    assert travelled > 3.0  # the cart really moved
    assert m.tracking_max_m < 0.02
    # every arm torque of every sample inside the iiwa's effortLimit (from the URDF)
    r = robots.load("ridgeback_iiwa")
    limits = np.array([r.model.effortLimit[r.model.joints[r.model.getJointId(f"iiwa_joint_{i}")].idx_v]
                       for i in range(1, 8)])
    assert np.all(np.abs(on.arm_torque) <= limits)
    assert m.arm_torque_limit_ratio < 1.0
    # the gripper stays on the handle and the hands produce the commanded motion-direction wrench
    assert m.grasp_error_max_m < 0.005
    body_d = np.array([cart_model.generalized_to_body(q, g) for q, g in zip(on.q_true, on.gamma_desired)])
    body_a = np.array([cart_model.generalized_to_body(q, g) for q, g in zip(on.q_true, on.gamma_applied)])
    np.testing.assert_allclose(body_a[:, [0, 2]], body_d[:, [0, 2]], atol=1e-6)
    assert m.saturated_steps == 0


def test_estimation_converges_and_no_estimation_tracks_worse(runs):
    on, off = runs
    assert on.metrics.mass_error_final_kg < 1.5  # from 4 kg off
    assert off.metrics.mass_error_final_kg == pytest.approx(4.0)
    # wrong mass without estimation: tracking measurably worse (several times the error)
    assert off.metrics.tracking_rms_m > 3.0 * on.metrics.tracking_rms_m
    assert off.metrics.tracking_max_m > 2.0 * on.metrics.tracking_max_m


def test_measured_wrench_is_noisy_applied_wrench(runs):
    on, _ = runs
    resid = on.gamma_measured - on.gamma_applied
    # F/T noise of 3 N per axis in the sensor frame -> about 3 N on fx, fy of the cart
    assert 2.0 < np.std(resid[:, 0]) < 4.5
    assert abs(np.mean(resid[:, 0])) < 0.5


def test_ft_round_trip_matches_planar_grasp_map():
    r = robots.load("ridgeback_iiwa")
    q_cart = np.array([1.0, -0.5, 0.7])
    mm = MobileManipulator(r, q_cart, 0.1, 0.1, grasp_rotation())
    f_b, tz = np.array([12.0, -5.0, 0.0]), 1.5
    R = np.array([[np.cos(0.7), -np.sin(0.7), 0], [np.sin(0.7), np.cos(0.7), 0], [0, 0, 1.0]])
    w_world = np.r_[R @ f_b, 0.0, 0.0, tz]
    _, _, oMee, oMft = mm.torques(np.zeros(10), np.zeros(10), 0.01, w_world)
    reading = ft_measurement(w_world, oMee, oMft, np.random.default_rng(0), SensorNoise(force=0.0, torque=0.0))
    gamma = ft_to_cart_gamma(reading, oMft, q_cart)
    target, _ = grasp_target(q_cart, np.zeros(3), 0.1, 0.0, grasp_rotation())
    p_b = np.array([-0.15, 0.1])
    expected = cart_model.contact_wrench_to_generalized(q_cart, p_b, f_b[:2], tz)
    np.testing.assert_allclose(gamma, expected, atol=2e-3)  # IK leaves < 1e-5 m of grasp error
    np.testing.assert_allclose(oMee.translation, target.translation, atol=1e-5)


def test_arm_torque_is_gravity_plus_jacobian_transpose_by_finite_differences():
    r = robots.load("ridgeback_iiwa")
    mm = MobileManipulator(r, np.zeros(3), 0.0, 0.0, grasp_rotation())
    w = np.array([20.0, -3.0, 5.0, 0.5, -0.2, 1.0])
    tau, push, oMee, _ = mm.torques(np.zeros(10), np.zeros(10), 0.01, w)
    q = mm.wb.to_pinocchio_q(mm.x)
    g = pin.computeGeneralizedGravity(r.model, r.model.createData(), q)[mm.wb.arm_idx_v]
    np.testing.assert_allclose(tau - push, g, atol=1e-9)
    # virtual work: push_j = w . dX/dq_j, finite differences of the ee pose
    eps = 1e-6
    for j in range(7):
        x = mm.x.copy()
        x[3 + j] += eps
        T = mm.wb.ee_placement(x)
        dp = (T.translation - oMee.translation) / eps
        dr = pin.log3(T.rotation @ oMee.rotation.T) / eps
        assert push[j] == pytest.approx(w[:3] @ dp + w[3:] @ dr, abs=1e-4)


def test_two_mobile_manipulators_share_the_wrench():
    res = run_push(PushConfig(n_arms=2, contact="fixed", **SHORT))
    assert res.arm_torque.shape[1] == 2
    assert res.metrics.tracking_max_m < 0.02
    assert res.metrics.arm_torque_limit_ratio < 1.0
    # both hands push (the total forward force is split between them)
    fwd = res.wrenches[:, :, 0]
    assert np.all(fwd[300] > 1.0)
    np.testing.assert_allclose(res.contact_y[0], [-0.2, 0.2])


def test_bad_configuration_raises_project_error():
    with pytest.raises(WholeBodyError):
        PushConfig(trajectory=3)
    with pytest.raises(WholeBodyError):
        PushConfig(n_arms=3)
    with pytest.raises(WholeBodyError):
        PushConfig(contact="best")


def test_cli_push_json_log_and_bad_input(tmp_path, capsys):
    import json

    from cart.logs import read_log
    from wholebody.cli import main

    rc = main(["push", "--trajectory", "1", "--duration", "8", "--contact", "fixed", "--json", "--out", str(tmp_path)])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("tracking_rms_m", "tracking_max_m", "arm_torque_rms_nm", "arm_torque_peak_nm",
                "mass_error_final_kg", "com_error_final_m"):
        assert np.isfinite(out[key])
    assert out["tracking_max_m"] >= out["tracking_rms_m"] > 0
    log = read_log(tmp_path / "push_log.csv")
    assert len(log) == 801 and log.has_velocities
    assert (tmp_path / "tracking_estimation.png").stat().st_size > 0
    assert main(["push", "--contact", "best"]) == 2
    assert main(["push", "--arms", "3"]) == 2
    assert "error" in capsys.readouterr().err
