"""Load changes in the push loop (`wholebody.push.load_change`): the cart's parameters compose with the load, a load
put in takes the cart's momentum, both plants change their cart, the run is judged against the truth at each instant
and its figures, page and what_happened show the step."""

from __future__ import annotations

import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from cart import model
from cart.estimation_metrics import estimation_errors
from cart.params import CartParams
from wholebody.errors import WholeBodyError
from wholebody.push import PushConfig, run_push
from wholebody.push import mujoco_cart
from wholebody.push.config import TRUE_CART
from wholebody.push.load_change import LoadChange, params_after, params_series, truth_schedule, velocity_after
from wholebody.push.report import build_scene, describe, load_change_lines, match_load_changes, push_figures, push_log

CART = CartParams(20.0, 0.3, 0.15, 2.3, 4.0)


def test_a_point_mass_composes_by_the_parallel_axis_theorem_and_taking_it_out_undoes_it():
    after = params_after(CART, LoadChange(5.0, 10.0, (0.6, -0.15)))
    assert after.m == pytest.approx(30.0) and (after.dx, after.dy) == pytest.approx((0.4, 0.05))
    # about the new CoM: the cart's I + its offset (0.1, 0.1), the load's offset (0.2, 0.2)
    assert after.I == pytest.approx(2.3 + 20.0 * 0.02 + 10.0 * 0.08)
    back = params_after(after, LoadChange(6.0, -10.0, (0.6, -0.15)))
    assert (back.m, back.dx, back.dy, back.I) == pytest.approx((20.0, 0.3, 0.15, 2.3))
    at_com = params_after(CART, LoadChange(5.0, 10.0))  # no place: at the CoM, which stays
    assert (at_com.dx, at_com.dy, at_com.I) == pytest.approx((0.3, 0.15, 2.3))


@pytest.mark.parametrize(
    "change", [LoadChange(5.0, -20.0), LoadChange(5.0, -25.0), LoadChange(5.0, -10.0, (1.5, 0.0))], ids=str
)
def test_taking_out_more_than_the_cart_holds_is_refused(change):
    with pytest.raises(WholeBodyError, match="more than"):
        params_after(CART, change)


def test_a_load_put_in_takes_the_momentum_the_wheels_allow_and_one_taken_out_leaves_the_velocity():
    """The impulse keeps N^T M qd (N: the motions the no-slip constraint allows, paper eq. 3) and the constraint;
    it dissipates energy (a perfectly inelastic catch)."""
    q, qd = np.array([1.0, 2.0, 0.7]), np.array([0.5 * math.cos(0.7), 0.5 * math.sin(0.7), 0.3])
    new = params_after(CART, LoadChange(1.0, 15.0, (0.6, -0.2)))
    after = velocity_after(q, qd, CART, new)
    free = np.array([[math.cos(0.7), 0.0], [math.sin(0.7), 0.0], [0.0, 1.0]])  # forward speed, yaw rate
    np.testing.assert_allclose(free.T @ model.mass_matrix(q, new) @ after, free.T @ model.mass_matrix(q, CART) @ qd)
    assert model.lateral_speed(q, after) == pytest.approx(0.0, abs=1e-12)
    energy = lambda v, p: 0.5 * v @ model.mass_matrix(q, p) @ v  # noqa: E731
    assert energy(after, new) < energy(qd, CART)
    assert np.array_equal(velocity_after(q, after, new, CART), after)


def test_the_truth_steps_at_each_change():
    changes = (LoadChange(8.0, -5.0), LoadChange(4.0, 10.0))
    schedule = truth_schedule(CART, changes)
    assert [(t, p.m) for t, p in schedule] == [(0.0, 20.0), (4.0, 30.0), (8.0, 25.0)]
    series = params_series(schedule, np.array([0.0, 3.99, 4.0, 7.0, 8.0, 9.0]))
    np.testing.assert_allclose(series[:, 0], [20.0, 20.0, 30.0, 30.0, 25.0, 25.0])


def test_a_config_refuses_a_change_outside_the_run_or_heavier_than_the_cart():
    with pytest.raises(WholeBodyError, match="outside the run"):
        PushConfig(duration=10.0, load_changes=(LoadChange(12.0, 10.0),))
    with pytest.raises(WholeBodyError, match="more than"):
        PushConfig(load_changes=(LoadChange(5.0, 10.0), LoadChange(6.0, -35.0)))


@pytest.fixture(scope="module")
def loaded_run():
    """Traj. 1 for 10 s on the kinematic plant, 10 kg put in at 5 s ahead of the CoM."""
    config = PushConfig(trajectory=1, duration=10.0, load_changes=(LoadChange(5.0, 10.0, (0.5, 0.0)),))
    return run_push(config)


def test_the_kinematic_plant_changes_its_cart_and_the_run_is_judged_against_the_truth_at_each_instant(loaded_run):
    r = loaded_run
    k = int(round(5.0 / r.config.dt))
    after = params_after(TRUE_CART, LoadChange(5.0, 10.0, (0.5, 0.0)))
    np.testing.assert_allclose(r.truth()[k - 1, :3], [20.0, 0.3, 0.15])
    np.testing.assert_allclose(r.truth()[k:, :4], np.tile([after.m, after.dx, after.dy, after.I], (len(r.t) - k, 1)))
    assert r.config.true_params == TRUE_CART  # the cart at the start; the truth over time is `truth()`
    (c,) = r.load_changes_true
    assert c["t_applied"] == pytest.approx(5.0) and (c["mass_before_kg"], c["mass_after_kg"]) == (20.0, 30.0)
    # the cart slows at the catch: its speed drops by about the mass ratio (the yaw rate takes a little)
    speed = np.hypot(r.qd_true[:, 0], r.qd_true[:, 1])
    assert speed[k + 1] < 0.8 * speed[k]
    m = r.phi_hat[:, 0]
    want = estimation_errors(r.t, m, r.phi_hat[:, 1:3] / m[:, None], r.truth()[:, 0], r.truth()[:, 1:3])
    assert r.metrics.mass_error_max_after_5s_kg == pytest.approx(want["mass_error_max_after_5s_kg"])
    assert r.metrics.mass_error_final_kg == pytest.approx(abs(m[-1] - 30.0), abs=0.05)


def test_the_figure_and_the_page_draw_the_truth_as_a_step(loaded_run):
    from wholebody.viz import Scene
    from wholebody.viz.push_charts import estimate_charts, estimate_marks

    r = loaded_run
    with Scene(["shopping_cart"]) as scene:
        estimate_charts(scene, r)
        mass = scene._charts[0]
    assert mass.truth is not None and mass.truth[0] == 20.0 and mass.truth[-1] == 30.0
    assert float(r.t[np.argmax(mass.truth > 25.0)]) == pytest.approx(5.0)
    assert (pytest.approx(5.0), "made") in estimate_marks(r)
    with build_scene(r) as scene:  # the page's read-outs: the truth's masses, and the true mass live
        readouts = {ro.label: ro for ro in scene._readouts}
    assert any("true 20 -> 30 kg" in label for label in readouts)
    now = readouts["  ... true mass now (loads put in / taken out)"].values
    assert now[0] == 20.0 and now[-1] == 30.0
    fig = push_figures({"run": r})["estimate"]
    (line,) = [ln for ln in fig.axes[0].get_lines() if ln.get_label() == "truth, run"]
    y = np.asarray(line.get_ydata())
    assert y[0] == 20.0 and y[-1] == 30.0 and np.count_nonzero(np.diff(y)) == 1


def test_what_happened_says_whether_each_change_was_found(loaded_run):
    found = {"t_change": 5.02, "t_detected": 5.3, "mass_before": 20.1, "mass_after": 29.4, "statistic": 30.0}
    early = {"t_change": 2.0, "t_detected": 2.5, "mass_before": 20.0, "mass_after": 22.0, "statistic": 20.0}
    report = {**(loaded_run.estimator_report or {}), "load_changes": [early, found]}
    (row,) = match_load_changes(replace(loaded_run, estimator_report=report))
    assert row["found"] and row["time_error_s"] == pytest.approx(0.02)
    assert row["mass_after_error_kg"] == pytest.approx(-0.6) and row["mass_after_error_pct"] == pytest.approx(-2.0)
    settled = loaded_run.phi_hat[-1, 0]  # the only change: the estimate at the run's end
    assert row["mass_settled_kg"] == settled and row["mass_settled_error_pct"] == pytest.approx(
        100 * (settled / 30 - 1)
    )
    lines = load_change_lines(replace(loaded_run, estimator_report=report))
    assert "found, dated 5.02 s (+0.02 s)" in lines[0] and "where none was made: t = 2.00" in lines[1]
    missed = load_change_lines(replace(loaded_run, estimator_report={**report, "load_changes": [early]}))
    assert "NOT found" in missed[0]
    # a change not found says what the pushes on each side weigh on their own: before it (5 s from the start) the
    # truth within 3 std; after it, 5 s of cruise whose filtered rows hold about 1 s, nothing, and the line says so
    (row,) = match_load_changes(replace(loaded_run, estimator_report={**report, "load_changes": [early]}))
    m, std = row["mass_alone_before_kg"], row["mass_alone_before_std_kg"]
    assert abs(m - 20.0) <= 3.0 * std and std < 10.0, (m, std)
    assert row["mass_alone_after_kg"] is None and row["mass_alone_after_std_kg"] is None
    assert "the pushes on one side of it say nothing of the mass" in missed[0], missed[0]
    # the rows a caller already matched are used as given, not matched (weighed) again
    given = [{**row, "mass_alone_after_kg": 31.0, "mass_alone_after_std_kg": 1.0}]
    again = load_change_lines(replace(loaded_run, estimator_report={**report, "load_changes": [early]}), given)
    assert again[1:] == missed[1:] and "NOT found" in again[0]
    assert f"{m:.1f} +- {std:.1f} and 31.0 +- 1.0 kg on their own" in again[0], again[0]
    assert describe(loaded_run.config).endswith("load +10 kg at 5 s")


def test_a_change_followed_by_one_not_found_is_weighed_before_that_one(loaded_run):
    """The estimator weighs its last change with its estimate at the run's end; when a true change it did not find
    came after, that end is the later cart's mass: the change is weighed with the loop's estimate before it."""
    found = {"t_change": 5.02, "t_detected": 5.3, "mass_before": 20.1, "mass_after": 99.0, "statistic": 30.0}
    first = loaded_run.load_changes_true[0]
    second = {**first, "t_applied": 8.0, "mass_kg": -5.0, "mass_after_kg": 25.0}
    run = replace(loaded_run, load_changes_true=(first, second), estimator_report={"load_changes": [found]})
    row, missed = match_load_changes(run)
    before_second = loaded_run.phi_hat[int(np.searchsorted(loaded_run.t, 8.0 - 1e-9)) - 1, 0]
    assert row["found"] and row["mass_after_est_kg"] == before_second != 99.0
    assert not missed["found"]
    alone = replace(loaded_run, estimator_report={"load_changes": [found]})
    assert match_load_changes(alone)[0]["mass_after_est_kg"] == 99.0  # the last true change: the estimator's own
    assert push_log(loaded_run).metadata["load_changes"] == "t=5 mass=+10 -> m=30"


def test_a_point_mass_in_a_mujoco_body_composes_and_taking_it_out_restores_the_body():
    m, d = mujoco_cart.build(mujoco_cart.shopping_cart(TRUE_CART))
    mujoco.mj_forward(m, d)
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, mujoco_cart.CART_BODY)
    before = mujoco_cart.composite_inertia(m, d, body)
    keep = [np.array(getattr(m, f)[body]) for f in ("body_mass", "body_ipos", "body_inertia")]
    mujoco_cart.add_point_mass(m, body, 10.0, (0.6, -0.15, 0.3))
    mujoco.mj_forward(m, d)
    mass, com, izz = mujoco_cart.composite_inertia(m, d, body)
    assert mass == pytest.approx(before[0] + 10.0)
    np.testing.assert_allclose(com[:2], (before[0] * before[1][:2] + 10.0 * np.array([0.6, -0.15])) / mass)
    shift = lambda c, mm: mm * float(np.sum((c[:2] - com[:2]) ** 2))  # noqa: E731
    assert izz == pytest.approx(before[2] + shift(before[1], before[0]) + shift(np.array([0.6, -0.15]), 10.0))
    mujoco_cart.add_point_mass(m, body, -10.0, (0.6, -0.15, 0.3))
    for f, v in zip(("body_mass", "body_ipos"), keep):
        np.testing.assert_allclose(getattr(m, f)[body], v, atol=1e-12)
    assert sorted(m.body_inertia[body]) == pytest.approx(sorted(keep[2]))
    with pytest.raises(WholeBodyError):
        mujoco_cart.add_point_mass(m, body, -1000.0, (0.3, 0.0, 0.3))


def test_the_mujoco_plant_changes_its_cart_and_keeps_the_momentum_of_a_load_put_in():
    from wholebody.push.loop import build_controller
    from wholebody.push.plants import make_plant, plant_truth_schedule

    config = PushConfig(
        trajectory=1, plant="mujoco", contact="fixed", load_changes=(LoadChange(0.01, 10.0, (0.5, 0.0)),)
    )
    plant = make_plant(config, build_controller(config))
    m, d = plant.scene.model, plant.scene.data
    d.qvel[plant.scene.cart_dof] = 0.5
    mujoco.mj_forward(m, d)
    M_old, v_old = np.zeros((m.nv, m.nv)), d.qvel.copy()
    mujoco.mj_fullM(m, d, M_old)
    plant.t = 0.01
    plant._apply_load_changes()
    M_new = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M_new)
    np.testing.assert_allclose(M_new @ d.qvel, M_old @ v_old, atol=1e-9)
    assert d.qvel[plant.scene.cart_dof] < 0.5 * 0.75  # 20.7 -> 30.7 kg: the forward speed drops about a third
    (_, before), (t, after) = plant_truth_schedule(config, plant)
    assert t == pytest.approx(0.01) and after.m == pytest.approx(before.m + 10.0)  # the effective mass
    (_, rigid0), (_, rigid1) = plant.inertial_log
    assert rigid1.com_b[0] == pytest.approx((rigid0.mass * rigid0.com_b[0] + 10.0 * 0.5) / rigid1.mass, abs=1e-3)


def test_the_mujoco_plant_refuses_a_removal_beyond_the_cart_body_before_the_run():
    """Loads come out of the cart file's body 'cart' alone (its wheels and welded bodies keep their mass): a removal
    the cart as a whole could give but that body cannot is refused when the plant is made, not when it is due (a
    change at 29 s failed after the run's first 29 s), with the body's mass and the cart's."""
    from wholebody.push.loop import build_controller
    from wholebody.push.mujoco_plant import MujocoPlantError
    from wholebody.push.plants import make_plant

    config = PushConfig(trajectory=1, plant="mujoco", contact="fixed", load_changes=(LoadChange(29.0, -19.0),))
    controller = build_controller(config)
    with pytest.raises(MujocoPlantError, match=r"t = 29 s takes out 19 kg .* body 'cart' holds .* of the cart's 20 kg"):
        make_plant(config, controller)
    ok = PushConfig(trajectory=1, plant="mujoco", contact="fixed", load_changes=(LoadChange(29.0, -2.0),))
    plant = make_plant(ok, build_controller(ok))
    cart = plant.scene.cart_body
    assert plant.scene.model.body_mass[cart] == pytest.approx(plant.inertial_log[0][1].mass, abs=20.0)
    before = float(plant.scene.model.body_mass[cart])
    assert plant._pending and before > 2.0  # the trial left the body as it was
    plant._check_cart_body_holds()
    assert float(plant.scene.model.body_mass[cart]) == before


@pytest.mark.parametrize("bad", ["12", "12:+0", "x:+10", "12:+10@0.4", "40:+10", "12:-25", "12:+10@1,2,3"])
def test_a_bad_load_change_is_one_line_and_exit_2(bad, capsys):
    from cartpush.cli import main

    assert main(["push", "--load-change", bad, "--json"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and ("load change" in err or "--load-change" in err)


def test_the_demo_puts_the_loads_into_every_run_and_refuses_a_bad_one(tmp_path, capsys):
    from cartpush.cli import main
    from wholebody.push.report import demo_configs

    loads = (LoadChange(5.0, 10.0),)
    assert all(c.load_changes == loads for c in demo_configs(10.0, load_changes=loads).values())
    assert main(["demo", "--duration", "10", "--load-change", "12:+10", "--out", str(tmp_path)]) == 2
    assert "outside the run (0, 10) s" in capsys.readouterr().err
