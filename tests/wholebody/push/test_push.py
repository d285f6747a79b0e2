"""Closed-loop push (wholebody.push): end to end, torque limits, estimation on/off, sensing and torque models."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

import robots
from cart import model as cart_model
from wholebody.errors import WholeBodyError
from wholebody.motion.control import ResolvedRateController
from wholebody.push import (
    BASE_OFFSET_X,
    PUSH_CONTROLLER,
    PushConfig,
    PUSH_SENSOR_NOISE,
    MobileManipulator,
    WholeBodyQPTracker,
    base_target,
    ft_measurement,
    ft_to_cart_gamma,
    grasp_rotation,
    grasp_target,
    handle_point,
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
    assert m.tracking_max_mm < 20.0
    # the metric is the largest distance of the {b} origin from the desired one, in mm
    err = np.hypot(*(on.q_true[:, :2] - on.q_desired[:, :2]).T)
    assert m.tracking_max_mm == pytest.approx(1e3 * err.max())
    assert m.tracking_rms_mm == pytest.approx(1e3 * np.sqrt(np.mean(err**2)))
    # every arm torque of every sample inside the iiwa's effortLimit (from the URDF)
    r = robots.load("ridgeback_iiwa")
    limits = np.array(
        [r.model.effortLimit[r.model.joints[r.model.getJointId(f"iiwa_joint_{i}")].idx_v] for i in range(1, 8)]
    )
    assert np.all(np.abs(on.arm_torque) <= limits)
    assert m.arm_torque_limit_ratio < 1.0
    # the gripper stays on the handle and the hands produce the commanded motion-direction wrench
    assert m.grasp_error_max_m < 0.005
    body_d = np.array([cart_model.generalized_to_body(q, g) for q, g in zip(on.q_true, on.gamma_desired)])
    body_a = np.array([cart_model.generalized_to_body(q, g) for q, g in zip(on.q_true, on.gamma_applied)])
    # the controller aligns the wrench with its estimated heading (motion capture: 3 mrad) and the hand pushes
    # where it is (at most grasp_error_max_m from the handle point): the torque differs by at most |f| x that
    f = np.linalg.norm(on.wrenches[:, 0, :2], axis=1)
    np.testing.assert_allclose(body_a[:, 0], body_d[:, 0], atol=0.01 * f.max())
    # ... and the heading error (3 mrad noise: 1 cm of a 0.3 m lever at 3 sigma) turns the force about the handle
    lever = f * (m.grasp_error_max_m + 0.3 * 0.01)
    assert np.all(np.abs(body_a[:, 2] - body_d[:, 2]) <= lever + 0.01 * np.abs(body_d[:, 2]) + 1e-9)
    assert m.saturated_steps == 0


def test_estimation_converges_and_no_estimation_tracks_worse(runs):
    on, off = runs
    assert on.metrics.mass_error_final_kg < 1.5  # from 4 kg off
    assert off.metrics.mass_error_final_kg == pytest.approx(4.0)
    # wrong mass without estimation: tracking measurably worse (several times the error)
    assert off.metrics.tracking_rms_mm > 3.0 * on.metrics.tracking_rms_mm
    assert off.metrics.tracking_max_mm > 2.0 * on.metrics.tracking_max_mm


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
    reading = ft_measurement(
        w_world, oMee, oMft, np.random.default_rng(0), replace(PUSH_SENSOR_NOISE, force=0.0, torque=0.0)
    )
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
    assert res.metrics.tracking_max_mm < 20.0
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
    from cartpush.cli import main

    rc = main(["push", "--trajectory", "1", "--duration", "8", "--contact", "fixed", "--json", "--out", str(tmp_path)])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    for key in (
        "tracking_rms_mm",
        "tracking_max_mm",
        "arm_torque_rms_nm",
        "arm_torque_peak_nm",
        "mass_error_final_kg",
        "com_error_final_m",
    ):
        assert np.isfinite(out[key])
    assert out["tracking_max_mm"] >= out["tracking_rms_mm"] > 0
    assert not any(k.startswith("tracking") and k.endswith("_m") for k in out)  # one unit: mm
    assert isinstance(out["mass_unobservable_s"], list) and isinstance(out["com_unobservable_s"], list)
    log = read_log(tmp_path / "push_log.csv")
    assert len(log) == 801 and log.has_velocities
    assert (tmp_path / "tracking_estimation.png").stat().st_size > 0
    assert main(["push", "--contact", "best"]) == 2
    assert main(["push", "--arms", "3"]) == 2
    assert "error" in capsys.readouterr().err


def test_default_tracker_is_the_wholebody_qp_within_base_limits_and_near_the_nominal_base(runs):
    on, _ = runs
    assert isinstance(
        MobileManipulator(robots.load("ridgeback_iiwa"), np.zeros(3), 0.0, 0.0, grasp_rotation()).tracker,
        WholeBodyQPTracker,
    )
    m = on.metrics
    assert m.base_wheel_limit_ratio <= 1.0 + 1e-9 and m.base_twist_limit_ratio <= 1.0 + 1e-9
    # the base stays near its nominal place 0.65 m behind its contact point (recomputed from the cart's pose)
    nominal = np.array(
        [
            base_target(q, np.zeros(3), np.array([handle_point(y)[0] + BASE_OFFSET_X, y]))[0]
            for q, y in zip(on.q_true, on.contact_y[:, 0])
        ]
    )
    dist = np.hypot(*(on.robot_x[:, 0, :2] - nominal[:, :2]).T)
    assert dist.max() < 0.05
    assert np.abs(on.robot_x[:, 0, 2] - nominal[:, 2]).max() < 0.05


def test_base_regularisation_term_matches_stacked_least_squares():
    """The controller's optional base pull equals the unconstrained least-squares optimum (no bound active)."""
    r = robots.load("ridgeback_iiwa")
    mm = MobileManipulator(r, np.array([0.5, 0.2, 0.3]), 0.05, 0.05, grasp_rotation())
    wb, cfg = mm.wb, PUSH_CONTROLLER
    x = mm.x + np.r_[0.01, -0.02, 0.01, 0.02 * np.ones(7)]  # perturbed: base and arm off target
    ctrl = ResolvedRateController(wb, cfg, posture=mm.x[3:])
    T_des = wb.ee_placement(mm.x)
    v_des = np.array([0.3, 0.1, 0.0, 0.0, 0.0, 0.2])
    b_des, b_vel = np.array([0.1, 0.15, 0.32]), np.array([0.25, -0.1, 0.2])
    res = ctrl.step(x, T_des, v_des, 0.01, base_target=b_des, base_target_velocity=b_vel)
    # independent: stack sqrt(weight) * (A u - b) rows and solve with numpy
    T, J = wb.ee_and_jacobian(x)
    e = np.r_[T_des.translation - T.translation, pin.log3(T_des.rotation @ T.rotation.T)]
    c, s_ = np.cos(x[2]), np.sin(x[2])
    w = b_vel + cfg.base_gain * (b_des - x[:3])
    twist = np.array([c * w[0] + s_ * w[1], -s_ * w[0] + c * w[1], w[2]])
    A = np.vstack(
        [
            J,
            np.sqrt(cfg.damping) * np.eye(10),
            np.sqrt(cfg.secondary_weight) * np.eye(10)[:7],
            np.sqrt(cfg.base_weight) * np.eye(10)[7:],
        ]
    )
    b = np.r_[
        v_des + cfg.gain * e,
        np.zeros(10),
        np.sqrt(cfg.secondary_weight) * cfg.posture_gain * (mm.x[3:] - x[3:]),
        np.sqrt(cfg.base_weight) * twist,
    ]
    u_ls = np.linalg.lstsq(A, b, rcond=None)[0]
    np.testing.assert_allclose(res.u, u_ls, atol=1e-6)
    # without a base target (or with weight 0) the term is off: a different input
    free = ResolvedRateController(wb, cfg, posture=mm.x[3:]).step(x, T_des, v_des, 0.01)
    assert np.linalg.norm(free.u[7:] - res.u[7:]) > 1e-3


def test_scene_animates_true_and_estimated_com_with_the_cart(runs):
    from wholebody.push.report import build_scene
    from wholebody.viz import COM_MARKER_Z

    on, _ = runs
    fps = 5
    keys = build_scene(on, fps=fps).animation_keys()
    assert "/meshcat/com/com_true" in keys and "/meshcat/com/com_est" in keys
    true_pos = keys["/meshcat/com/com_true"]["position"]
    est_pos = keys["/meshcat/com/com_est"]["position"]
    # the page samples the run every 1/fps s; each frame shows the latest sample at or before its time
    sampled = np.arange(0, len(on.t), int(round(1.0 / (fps * on.config.dt))))
    ts = on.t[sampled]
    frames = sampled[np.searchsorted(ts, ts[0] + np.arange(len(true_pos)) / fps, side="right") - 1]
    q = on.q_true[frames]
    p = on.config.true_params
    # true CoM = cart pose applied to (dx, dy), recomputed here; it moves with the cart (> 3 m)
    expected = np.column_stack(
        [
            q[:, 0] + np.cos(q[:, 2]) * p.dx - np.sin(q[:, 2]) * p.dy,
            q[:, 1] + np.sin(q[:, 2]) * p.dx + np.cos(q[:, 2]) * p.dy,
        ]
    )
    np.testing.assert_allclose(true_pos[:, :2], expected, atol=1e-9)
    np.testing.assert_allclose(true_pos[:, 2], COM_MARKER_Z, atol=1e-12)
    assert np.hypot(*(true_pos[-1, :2] - true_pos[0, :2])) > 3.0
    phi = on.phi_hat[frames]
    est_b = np.column_stack([phi[:, 1] / phi[:, 0], phi[:, 2] / phi[:, 0]])
    est_expected = np.column_stack(
        [
            q[:, 0] + np.cos(q[:, 2]) * est_b[:, 0] - np.sin(q[:, 2]) * est_b[:, 1],
            q[:, 1] + np.sin(q[:, 2]) * est_b[:, 0] + np.cos(q[:, 2]) * est_b[:, 1],
        ]
    )
    np.testing.assert_allclose(est_pos[:, :2], est_expected, atol=1e-9)


def test_unobservable_intervals_flag_where_the_std_grows():
    from wholebody.push.loop import unobservable_intervals

    t = np.arange(0.0, 10.0001, 0.01)
    # shrinks until 2 s, grows 2-6 s, shrinks 6-8 s, grows 8-8.8 s (too short), then flat
    std = np.interp(t, [0.0, 2.0, 6.0, 8.0, 8.8, 10.0], [1.0, 0.2, 0.5, 0.3, 0.35, 0.35])
    spans = unobservable_intervals(t, std)
    assert len(spans) == 1
    # the edges are known to within half the 0.5 s comparison window
    assert spans[0][0] == pytest.approx(2.0, abs=0.25) and spans[0][1] == pytest.approx(6.0, abs=0.25)
    assert unobservable_intervals(t, np.full_like(t, np.nan)) == ()


def test_run_records_the_ekf_std_and_flags_the_straight_cruise(runs):
    """On the straight Traj. 1 the cruise (constant speed, no turn) carries no information on the mass (EKF)."""
    _, off = runs
    on = run_push(PushConfig(estimation=True, estimator="ekf", contact="fixed", fixed_contact_y=(0.0,), **SHORT))
    assert on.param_std.shape == (len(on.t), 4) and np.all(on.param_std > 0)
    np.testing.assert_allclose(on.param_std[:, 1], np.hypot(on.param_std[:, 2], on.param_std[:, 3]))
    m = on.metrics
    cruise = [(a, b) for a, b in m.mass_unobservable_s if b - a > 2.0]
    assert cruise, m.mass_unobservable_s
    a, b = cruise[0]
    k0, k1 = int(round(a / 0.01)), int(round(b / 0.01))
    assert on.param_std[k1, 0] > on.param_std[k0, 0]  # independent check: the recorded 1-sigma grew
    assert np.all(np.abs(on.q_true[k0 + 50 : k1, 2] - on.q_true[k0 + 50, 2]) < 0.05)  # no turning meanwhile
    assert off.metrics.mass_unobservable_s == () and off.metrics.com_unobservable_s == ()  # nothing estimated


def test_the_online_estimator_says_what_a_straight_push_does_not_excite(runs):
    """A straight push says nothing about the CoM's x: the online estimate keeps the prior there and says so."""
    on, off = runs
    report = on.estimator_report
    assert "dx" in report["unexcited"]
    assert report["load_changes"] == []
    assert abs(on.phi_hat[-1, 1] / on.phi_hat[-1, 0] - on.config.initial_com[0]) < 0.02  # dx held at the guess
    assert off.estimator_report == {}  # estimation off: the frozen EKF reports nothing


def test_estimation_figure_draws_error_bands_and_unobservable_stretches(runs):
    from wholebody.push.report import push_figures

    on, off = runs
    figs = push_figures({"with estimation": on, "without estimation": off})
    axes = figs["tracking_estimation"].axes
    assert "[mm]" in axes[0].get_ylabel() and "[kg]" in axes[1].get_ylabel() and "[cm]" in axes[2].get_ylabel()
    for ax, unit in ((axes[1], "within 1 kg"), (axes[2], "within 1 cm")):
        labels = ax.get_legend_handles_labels()[1]
        assert unit in labels
        band = ax.patches[[p.get_label() for p in ax.patches].index(unit)]
        assert band.get_y() == pytest.approx(0.0) and band.get_y() + band.get_height() == pytest.approx(1.0)
    shaded = [p for p in axes[1].patches if p.get_label().startswith("mass unobservable")]
    assert bool(shaded) == bool(on.metrics.mass_unobservable_s)
    # the plotted mass error is |m_hat - m| of the run (independent of the metric code)
    line = axes[1].get_lines()[0]
    np.testing.assert_allclose(line.get_ydata(), np.abs(on.phi_hat[:, 0] - on.config.true_params.m))
    # every cart and base trace of the path figure is in its legend
    assert len(figs["path"].axes[0].get_legend().get_texts()) == 1 + 2 * 2
