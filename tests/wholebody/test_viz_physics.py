"""The figures and the Meshcat page of a physics run: allocated vs measured hand wrench, casters, the estimate
with its band against the truth, the loss of the cart marked."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from wholebody.push import PushConfig, run_push
from wholebody.push.report import (
    base_lateral_speed,
    before_loss,
    _in_b,
    allocated_cart_wrench,
    build_scene,
    caster_swivel,
    produced_cart_wrench,
    push_figures,
)

DT = 0.01
TRAIL = 0.03
PIVOT = np.array([[0.78, 0.2]])


@pytest.fixture(scope="module")
def physics():
    """A short MuJoCo run, one Ridgeback + iiwa (4-5 s CPU)."""
    return run_push(PushConfig(trajectory=2, duration=8.0, plant="mujoco", contact="fixed"))


@pytest.fixture(scope="module")
def kinematic():
    return run_push(PushConfig(trajectory=2, duration=8.0, contact="fixed"))


def _turning(v: float, w: float, n: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """Return the poses and velocities in {s} of a cart driving at v (forward, m/s) turning at w (rad/s)."""
    th = w * DT * np.arange(n)
    q = np.column_stack([np.zeros(n), np.zeros(n), th])  # positions do not enter the swivel
    qd = np.column_stack([v * np.cos(th), v * np.sin(th), np.full(n, w)])
    return q, qd


def test_a_caster_settles_on_its_pivots_motion_and_swings_round_when_the_cart_reverses():
    q, qd = _turning(0.5, 0.4)
    psi = caster_swivel(q, qd, DT, PIVOT, TRAIL)[-1, 0]
    u = np.array([math.cos(psi), math.sin(psi)])  # the wheel's rolling direction in {b}
    c = PIVOT[0] - TRAIL * u  # its contact point, behind the pivot
    vc = np.array([0.5 - 0.4 * c[1], 0.4 * c[0]])  # v_b + w x c, in {b}
    assert abs(u[0] * vc[1] - u[1] * vc[0]) < 1e-4 * np.linalg.norm(vc) and u @ vc > 0  # rolls, no side slip
    assert psi > 0.5  # turning left: the caster has swung well round
    straight = caster_swivel(*_turning(0.5, 0.0), DT, PIVOT, TRAIL)
    assert np.abs(straight).max() == 0.0  # pushed straight ahead it trails, unmoved
    q, qd = _turning(0.5, 0.0)
    qd[:, 0] = np.where(np.arange(len(q)) < 100, 0.5, -0.5)  # then pulled back
    qd[:, 2] = np.where(np.arange(len(q)) == 100, 0.05, 0.0)  # a nudge off the unstable balance
    back = caster_swivel(q, qd, DT, PIVOT, TRAIL)
    assert abs(abs(back[-1, 0]) - math.pi) < 1e-2  # the wheel now trails on the other side


def test_the_kinematic_plant_applies_exactly_the_allocated_wrench(kinematic):
    """The grasp map of the allocated hand wrenches (eq. 23-24) is the wrench the kinematic plant applied."""
    a, applied = allocated_cart_wrench(kinematic), _in_b(kinematic, kinematic.gamma_applied)
    scale = np.abs(applied).max(axis=0)
    assert np.all(np.abs(a - applied).max(axis=0) < 0.02 * scale + 0.05)  # the hand sits within mm of the handle


def test_the_measured_wrench_is_compared_with_the_allocation_it_answers(physics):
    """MuJoCo reports the F/T wrench of the period just ended: aligned, the error is the plant's own figure."""
    a, produced = allocated_cart_wrench(physics), produced_cart_wrench(physics)
    unshifted = _in_b(physics, physics.gamma_applied)
    rms = lambda e: float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, axis=1))))
    assert rms(produced - a) < rms(unshifted - a)
    assert rms(produced - a) == pytest.approx(physics.plant_report["wrench_error_rms_n"], rel=0.15)


def test_figures_show_the_estimate_with_its_band_against_the_plants_truth(physics, kinematic):
    figs = push_figures({"MuJoCo": physics, "kinematic": kinematic})
    mass = figs["estimate"].axes[0]
    line = mass.get_lines()[0]
    np.testing.assert_allclose(line.get_ydata(), physics.phi_hat[:, 0])
    truths = [ln.get_ydata()[0] for ln in mass.get_lines() if ln.get_label().startswith("truth")]
    assert truths == pytest.approx([physics.plant_report["cart_mass_effective_kg"], kinematic.config.true_params.m])
    assert any(lab.startswith("+-1-sigma, MuJoCo") for lab in mass.get_legend_handles_labels()[1])
    wrench = figs["hand_wrenches"].axes[0]
    labels = [ln.get_label() for ln in wrench.get_lines()]
    assert "allocated to the hands (eq. 25)" in labels and any("F/T sensors" in lab for lab in labels)


def test_a_lost_cart_is_marked_on_the_figures_and_the_page(physics):
    lost = replace(physics, metrics=replace(physics.metrics, tracking_lost_at_s=5.0))
    figs = push_figures({"lost": lost})
    for name in ("estimate", "hand_wrenches"):
        labels = figs[name].axes[0].get_legend_handles_labels()[1]
        assert "cart lost (a failed push)" in labels, name
    kept = replace(physics, metrics=replace(physics.metrics, tracking_lost_at_s=None))
    assert (
        "cart lost (a failed push)"
        not in push_figures({"kept": kept})["estimate"].axes[0].get_legend_handles_labels()[1]
    )
    readouts = {r.label: r for r in build_scene(lost, fps=5)._readouts}
    event = next(r for label, r in readouts.items() if label.startswith("cart LOST"))
    assert np.isnan(event.values[event.t < 5.0]).all() and np.all(event.values[event.t >= 5.0] == 5.0)


def test_the_physics_page_draws_allocated_and_measured_force_and_swivelling_casters(physics, kinematic):
    scene = build_scene(physics, fps=5)
    keys = scene.animation_keys()
    assert "/meshcat/wrenches/measured/hand" in keys and "/meshcat/wrenches/allocated/allocated" in keys
    texts = [e.text for e in scene.legend()]
    assert any("F/T sensor measured" in t for t in texts) and any("allocation asked" in t for t in texts)
    fork = keys["/meshcat/shopping_cart/visuals/caster_left_fork_0"]["quaternion"]
    assert np.ptp(2 * np.arctan2(fork[:, 2], fork[:, 3])) > 0.1  # Traj. 2 turns: the caster swivels
    # the kinematic plant applies the allocation: one arrow, the hand's force
    plain = build_scene(kinematic, fps=5).animation_keys()
    assert "/meshcat/wrenches/applied/hand" in plain and not any("measured" in k for k in plain)


def test_before_loss_reports_the_push_up_to_the_loss(physics):
    whole = before_loss(physics)
    if physics.metrics.tracking_lost_at_s is None:
        assert whole["tracking_rms_mm"] == pytest.approx(physics.metrics.tracking_rms_mm, rel=1e-9)
        assert whole["arm_torque_limit_ratio"] == pytest.approx(physics.metrics.arm_torque_limit_ratio, rel=1e-9)
    lost = replace(physics, metrics=replace(physics.metrics, tracking_lost_at_s=5.0))
    b = before_loss(lost)
    keep = physics.t < 5.0
    err = np.hypot(*(physics.q_true[keep, :2] - physics.q_desired[keep, :2]).T)
    assert b["tracking_lost_at_s"] == 5.0 and b["valid_until_s"] == pytest.approx(4.99)
    assert b["tracking_rms_mm"] == pytest.approx(1e3 * np.sqrt(np.mean(err**2)), rel=1e-9)
    k = int(np.flatnonzero(keep)[-1])
    assert b["mass_error_kg"] == pytest.approx(abs(physics.phi_hat[k, 0] - physics.config.true_params.m))
    assert b["tracking_max_mm"] <= whole["tracking_max_mm"] + 1e-9


def test_base_lateral_speed_is_the_sideways_motion_in_the_bases_frame(physics):
    n, th, v = len(physics.t), 0.5, 0.3
    x = physics.robot_x.copy()
    side = np.array([-math.sin(th), math.cos(th)])  # the base's y axis in the world
    x[:, 0, :2] = np.outer(physics.t, v * side + 0.8 * np.array([math.cos(th), math.sin(th)]))
    x[:, 0, 2] = th
    assert base_lateral_speed(replace(physics, robot_x=x))[:, 0] == pytest.approx(np.full(n, v))


def test_the_table_marks_a_lost_run_and_gives_its_figures_before_the_loss(physics):
    from wholebody.push.report import comparison_table

    lost = replace(physics, metrics=replace(physics.metrics, tracking_lost_at_s=5.0))
    lines = comparison_table({"this run": lost}).splitlines()
    assert len(lines) == 3 and "(whole run: a failed push)" in lines[1]
    before = lines[2].split()
    assert " ".join(before[:8]) == "this run before the loss at 5.00 s"
    assert float(before[8]) == pytest.approx(before_loss(lost)["tracking_rms_mm"], abs=0.006)
    assert len(comparison_table({"this run": physics}).splitlines()) == 2 + (
        physics.metrics.tracking_lost_at_s is not None
    )


@pytest.mark.parametrize("name, pivot, trail", [("shopping_cart", (0.78, 0.2), 0.03), ("wmra", None, 0.04)])
def test_every_caster_of_a_model_swivels_by_its_own_pivot_and_trail(name, pivot, trail):
    import pinocchio as pin

    import robots
    from wholebody.push.report import swivel_casters

    model = robots.load(name).model
    q, qd = _turning(0.5, 0.4)
    rest = np.tile(pin.neutral(model)[4:], (len(q), 1))
    out = swivel_casters(model, rest, q, qd, DT)
    jid = model.getJointId("caster_left_swivel")
    k = model.idx_qs[jid] - 4
    p = np.asarray(model.jointPlacements[jid].translation[:2]) if pivot is None else np.array(pivot)
    expected = caster_swivel(q, qd, DT, p[None, :], trail)[:, 0]
    np.testing.assert_allclose(np.arctan2(out[:, k + 1], out[:, k]), np.angle(np.exp(1j * expected)), atol=1e-9)
    assert np.ptp(expected) > 0.3  # it turned
    others = np.ones(rest.shape[1], dtype=bool)
    for side in ("left", "right"):
        j = model.idx_qs[model.getJointId(f"caster_{side}_swivel")] - 4
        others[j : j + 2] = False
    np.testing.assert_array_equal(out[:, others], rest[:, others])  # nothing else moved
