"""What a push run says of itself (wholebody.push.report.what_happened): a hand off the handle, a slowed reference that
reached only part of the trajectory, a CoM the pushes did not identify."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from wholebody.push.report import HAND_OFF_HANDLE_M, _hand_off_handle


def _result(err: np.ndarray, dt: float = 0.01) -> SimpleNamespace:
    return SimpleNamespace(t=dt * np.arange(err.shape[0]), grasp_error=err, config=SimpleNamespace(dt=dt))


def test_a_hand_off_the_handle_is_reported_with_when_how_long_and_how_far():
    err = np.full((1000, 2), 0.001)
    err[400:520, 1] = 0.16 * np.sin(np.linspace(0.0, math.pi, 120))  # hand 2 swings 160 mm off from 4 s
    lines = _hand_off_handle(_result(err), math.inf)
    assert len(lines) == 1 and lines[0].startswith("HAND OFF THE HANDLE: hand 2")
    off = int(np.sum(err[:, 1] > HAND_OFF_HANDLE_M))
    assert f"for {0.01 * off:.2f} s" in lines[0] and "at most 160 mm" in lines[0]
    assert f"from t = {0.01 * int(np.argmax(err[:, 1] > HAND_OFF_HANDLE_M)):.2f} s" in lines[0]


def test_a_hand_on_the_handle_or_off_only_after_the_loss_says_nothing():
    err = np.full((1000, 1), 0.001)
    assert _hand_off_handle(_result(err), math.inf) == []
    err[800:, 0] = 0.3  # after the cart was lost at 7 s: a failed push, not an arm that could not follow
    assert _hand_off_handle(_result(err), 7.0) == []
    assert "the hand was" in _hand_off_handle(_result(err), math.inf)[0]


def test_a_run_that_reached_a_fraction_of_the_trajectory_does_not_read_plainly_tracked():
    from wholebody.push.report import _outcome

    t = 0.01 * np.arange(3001)
    metrics = SimpleNamespace(tracking_lost_at_s=None, tracking_rms_mm=42.6, tracking_max_mm=76.8)
    slowed = SimpleNamespace(t=t, metrics=metrics, reference_time=0.32 * t)  # at 32 % of the speed throughout
    assert _outcome(slowed).startswith("tracked the slowed reference: 42.6 mm RMS")
    assert "reached only the trajectory's t = 9.6 s of 30.0 s" in _outcome(slowed)
    held = dict(grasp_error=np.full((t.size, 1), 0.001), config=SimpleNamespace(dt=0.01))
    nearly = SimpleNamespace(t=t, metrics=metrics, reference_time=np.minimum(t, 28.0), **held)  # 2 s behind: 93 %
    assert _outcome(nearly) == "tracked: 42.6 mm RMS, 76.8 mm max"


def test_a_cart_on_its_path_with_the_hand_off_the_handle_does_not_read_tracked():
    from wholebody.push.report import _outcome

    t = 0.01 * np.arange(3001)
    err = np.full((t.size, 1), 0.001)
    err[1800:2600, 0] = 0.358  # the kinematic plant: the cart follows the planned wrench, the arm lags behind
    metrics = SimpleNamespace(tracking_lost_at_s=None, tracking_rms_mm=1.6, tracking_max_mm=6.3)
    run = SimpleNamespace(t=t, metrics=metrics, reference_time=t, grasp_error=err, config=SimpleNamespace(dt=0.01))
    assert _outcome(run).startswith("cart on its path but NOT HELD there: 1.6 mm RMS, 6.3 mm max")


def test_the_fit_sentence_says_when_the_pushes_leave_the_com_unidentified():
    from wholebody.push.report import _fit

    def result(unexcited):
        return SimpleNamespace(
            estimator_report={"residual_ratio": [0.9], "unexcited": unexcited},
            truth=lambda: np.array([[150.0, 0.97, 0.05, 30.0, 1.0]]),
            metrics=SimpleNamespace(mass_final_kg=148.0, com_error_final_m=0.02),
            config=SimpleNamespace(estimation=True, initial_com=(0.3, 0.0)),
        )

    assert "not identified" not in _fit(result([]))
    assert "CoM dx not identified by these pushes" in _fit(result(["dx", "inertia"]))


def test_a_com_estimate_worse_than_the_initial_guess_is_called_out():
    """The paper's EKF in MuJoCo ends its CoM 1.5 m from the truth with no flag of its own: the fit sentence says
    so for any estimator; an estimate less than COM_RUNOFF_M farther than the guess (18 cm for a guess 18 cm off
    read "farther than the initial guess (18 cm)"), or estimation off, says nothing."""
    from wholebody.push.report import COM_RUNOFF_M, _fit

    def result(err: float, estimation: bool = True, guess=(0.3, 0.0)):
        return SimpleNamespace(
            estimator_report={},
            truth=lambda: np.array([[20.7, 0.45, 0.0, 3.0, 1.0]]),  # the guess 15 cm from the truth
            metrics=SimpleNamespace(mass_final_kg=22.8, com_error_final_m=err),
            config=SimpleNamespace(estimation=estimation, initial_com=guess),
        )

    line = _fit(result(1.544))
    assert "CoM estimate 154 cm from the truth, farther than the initial guess (15 cm)" in line, line
    assert "CoM estimate" not in _fit(result(0.14)) and "CoM estimate" not in _fit(result(1.544, estimation=False))
    assert "CoM estimate" not in _fit(result(0.15 + 0.9 * COM_RUNOFF_M))
    assert "CoM estimate" in _fit(result(0.15 + 1.1 * COM_RUNOFF_M))


def test_an_estimate_far_from_the_initial_guess_names_the_options():
    """A 300 kg pallet from the 16 kg default guess: the sentence says how far and which options give a guess; an
    estimate within 3 x of the guess, or estimation off, says nothing."""
    from wholebody.push.report import _far_guess

    def run(mass: float, estimation: bool = True, flags=(), truth: float = 300.0) -> SimpleNamespace:
        return SimpleNamespace(
            config=SimpleNamespace(estimation=estimation, initial_mass=16.0),
            metrics=SimpleNamespace(mass_final_kg=mass),
            estimator_report={"runoff_flags": list(flags)},
            truth=lambda: np.array([[truth, 0.3, 0.0, 3.0, 1.0]]),
        )

    (line,) = _far_guess(run(196.6))
    assert "12.3 x the initial guess (196.6 kg for 16 kg)" in line and "--initial-mass" in line
    assert "0.2 x" in _far_guess(run(3.0))[0]
    assert _far_guess(run(40.0)) == [] and _far_guess(run(196.6, estimation=False)) == []
    # the estimate restarted from the pushes (flag guess_far): it is not held back, and the sentence says so
    (line,) = _far_guess(run(180.7, flags=[{"t": 1.91, "kind": "guess_far", "detail": ""}]))
    assert "restarted from them at t = 1.91 s and ended at 180.7 kg" in line and "holds the estimate back" not in line
    # an estimate that reached the cart's mass (a load put in: 80 + 40 kg from a 16 kg guess) is not held back
    (line,) = _far_guess(run(120.4, truth=120.3))
    assert "on the cart's mass (120.4 kg for 120.3 kg)" in line and "holds the estimate back" not in line


def test_a_loss_while_the_controller_took_the_cart_for_far_lighter_names_the_guess():
    """The hospital bed at 495 kg lost at 2.22 s from the 16 kg default guess: the sentence names both masses; a
    loss with the mass near the cart's, or no loss, says nothing."""
    from wholebody.push.report import _lost_to_guess

    def run(lost, m_hat: float, estimation: bool = True) -> SimpleNamespace:
        t = 0.01 * np.arange(800)
        m = np.where(t < 3.1, m_hat, 527.0)  # the estimate restarts from the pushes after the loss
        return SimpleNamespace(
            t=t,
            phi_hat=np.column_stack([m, 0.3 * m, 0.0 * m, m]),
            truth=lambda: np.tile([495.2, 0.8, 0.0, 80.0, 1.0], (t.size, 1)),
            metrics=SimpleNamespace(tracking_lost_at_s=lost),
            config=SimpleNamespace(estimation=estimation, initial_mass=16.0),
        )

    (line,) = _lost_to_guess(run(2.22, 16.0))
    assert "took the cart for 16.0 kg (its estimate, from the initial guess of 16 kg)" in line
    assert "it weighs 495.2 kg (31 x)" in line and "--initial-mass" in line
    assert "the initial guess, frozen" in _lost_to_guess(run(2.22, 16.0, estimation=False))[0]
    assert _lost_to_guess(run(None, 16.0)) == [] and _lost_to_guess(run(2.22, 480.0)) == []


def test_wheels_at_their_speed_limit_are_reported_with_when_and_how_long():
    from wholebody.push.report import WHEEL_LIMIT_TIME, _wheels_at_limit

    limit = np.array([10.0, 10.0])
    rates = np.full((1000, 1, 2), 4.0)
    rates[300:420, 0, 1] = -10.0  # the right wheel at its limit (backwards) for 1.2 s from 3 s
    run = SimpleNamespace(
        t=0.01 * np.arange(1000), wheel_rates=rates, wheel_velocity_limit=limit, config=_result(rates).config
    )
    line = _wheels_at_limit(run, math.inf)
    assert len(line) == 1 and "at their speed limit for 1.20 s from t = 3.00 s" in line[0], line
    assert _wheels_at_limit(run, 3.5) and "for 0.50 s" in _wheels_at_limit(run, 3.5)[0]  # before a loss at 3.5 s
    rates[300 + int(100 * WHEEL_LIMIT_TIME) - 1 : 420, 0, 1] = 9.9  # under WHEEL_LIMIT_TIME at the limit: nothing
    assert _wheels_at_limit(run, math.inf) == []


def test_a_lost_mujoco_run_names_robot_bodies_left_without_mass(tmp_path):
    """The WMRA's chassis without its <inertial> (100 kg): a lost run or slipping wheels on the MuJoCo plant name it;
    a run that went well, or the shipped URDF, say nothing."""
    import re

    import robots
    from robots.checks import massless_bodies
    from tests.robots.profile_files import write_profile
    from tests.robots.test_profiles import WMRA, wmra_text
    from wholebody.push.report import _massless_bodies

    text = re.sub(r'(<link name="base_link">)\s*<inertial>.*?</inertial>', r"\1", WMRA.read_text(), count=1, flags=re.S)
    (tmp_path / "wmra.urdf").write_text(text)
    path = write_profile(tmp_path, wmra_text())
    assert massless_bodies(WMRA.read_text()) == [] and [n for n, _ in massless_bodies(text)] == ["base_link"]
    # the Ridgeback's pedestal (40 L, its mass carried by no link) is a fifth of the robot's bulk: not named
    ridgeback = robots.urdf_path("ridgeback_iiwa").read_text()
    assert massless_bodies(ridgeback) == [] and [n for n, _ in massless_bodies(ridgeback, min_share=0.0)] == [
        "arm_mount_link"
    ]

    def run(lost, slip, plant="mujoco"):
        return SimpleNamespace(
            plant_report={"plant": plant, "base_wheel_slip_max_m_s": slip},
            metrics=SimpleNamespace(tracking_lost_at_s=lost),
            config=SimpleNamespace(robot=str(path)),
        )

    said = _massless_bodies(run(2.7, 0.02))
    assert len(said) == 1 and "'base_link'" in said[0] and "give them their mass" in said[0]
    assert _massless_bodies(run(None, 0.5)) == said
    assert _massless_bodies(run(None, 0.02)) == [] and _massless_bodies(run(2.7, None, "kinematic")) == []


def test_an_arm_body_without_mass_is_named(tmp_path):
    """The WMRA's arm_link3 without its <inertial>: the arm's torques leave its weight out (the kinematic plant runs
    it; MuJoCo refuses it); the shipped robots say nothing."""
    import re

    from tests.robots.profile_files import write_profile
    from tests.robots.test_profiles import WMRA, wmra_text
    from wholebody.push.report import _massless_arm_bodies

    text = re.sub(r'(<link name="arm_link3">)\s*<inertial>.*?</inertial>', r"\1", WMRA.read_text(), count=1, flags=re.S)
    assert text != WMRA.read_text()
    (tmp_path / "wmra.urdf").write_text(text)
    said = _massless_arm_bodies(
        SimpleNamespace(config=SimpleNamespace(robot=str(write_profile(tmp_path, wmra_text()))))
    )
    assert len(said) == 1 and "'arm_joint3'" in said[0] and "leave that weight out" in said[0], said
    for robot in ("wmra", "ridgeback_iiwa", "robots/examples/tiago_dual.toml"):
        assert _massless_arm_bodies(SimpleNamespace(config=SimpleNamespace(robot=robot))) == []


def test_a_load_change_not_found_says_whether_the_pushes_could_show_it():
    """The masses the pushes on each side weigh on their own against the change's size: under CHANGE_SEEN_SIGMA
    stds of their difference the motion could not tell it (the MuJoCo Traj. 2 with 5 kg lifted out at 15 s: 20.6
    +- 5.2 and 18.1 +- 1.6 kg, 0.9 std); above, the change was there to see."""
    from wholebody.push.report import CHANGE_SEEN_SIGMA, _information_after

    def row(before, after, mass=-5.0):
        return {
            "mass_kg": mass,
            "mass_alone_before_kg": before[0],
            "mass_alone_before_std_kg": before[1],
            "mass_alone_after_kg": after[0],
            "mass_alone_after_std_kg": after[1],
        }

    line = _information_after(row((20.6, 5.2), (18.1, 1.6)))
    assert "20.6 +- 5.2 and 18.1 +- 1.6 kg" in line and "a 5 kg change is 0.9 std" in line
    assert "too little motion to tell it" in line
    std = 5.0 / (CHANGE_SEEN_SIGMA + 0.1)  # each side's std: the change just above the threshold
    assert _information_after(row((20.6, std / math.sqrt(2)), (15.9, std / math.sqrt(2)))).endswith("there to see")
    assert "say nothing of the mass" in _information_after(row((20.6, 5.2), (None, None)))


def _wmra_with_wheel_effort(folder, effort: str) -> str:
    from pathlib import Path

    from tests.robots.profile_files import wmra_variant

    text = (Path(__file__).resolve().parents[3] / "robots" / "wmra.urdf").read_text()
    limit = '<limit effort="60" velocity="8.8"/>'
    return wmra_variant(folder, "wmra_wheels", text.replace(limit, f'<limit effort="{effort}" velocity="8.8"/>'))


def _push_run(robot: str, accel: float, push: float) -> SimpleNamespace:
    """A run whose one base accelerates at `accel` m/s^2 for 1 s while its hand pushes the cart with `push` N."""
    t = 0.01 * np.arange(300)
    twist = np.zeros((t.size, 1, 3))
    twist[:, 0, 0] = accel * np.clip(t - 1.0, 0.0, 1.0)
    wrenches = np.zeros((t.size, 1, 6))
    wrenches[:, 0, 0] = np.where(t >= 1.0, push, 0.0)
    cfg = SimpleNamespace(dt=0.01, robot=robot)
    return SimpleNamespace(t=t, base_twist=twist, wrenches=wrenches, config=cfg, robot_arms=(0,))


def test_wheels_too_weak_for_the_push_are_named_with_the_force_needed(tmp_path):
    from wholebody.push.report import _wheel_traction

    weak = _wmra_with_wheel_effort(tmp_path, "0.5")  # 2 x 0.5 N m on 0.17 m wheels: 5.9 N at the rims
    lines = _wheel_traction(_push_run(weak, accel=0.5, push=30.0), math.inf)
    assert len(lines) == 1 and "give at most 6 N" in lines[0]
    assert "needed up to 91 N" in lines[0]  # 121.1 kg x 0.5 m/s^2 + 30 N
    assert _wheel_traction(_push_run("wmra", accel=0.5, push=30.0), math.inf) == []  # 2 x 60 N m: 706 N
    assert _wheel_traction(_push_run(weak, accel=0.5, push=30.0), 0.5) == []  # the need came after the loss


def test_a_cart_that_tipped_says_so_with_when_and_how_far():
    from wholebody.push.report import _tipped

    assert _tipped({"cart_tipped_at_s": None, "cart_tilt_max_deg": 1.2}) == []
    assert _tipped({}) == []  # the kinematic plant: no tilt
    line = _tipped({"cart_tipped_at_s": 0.09, "cart_tilt_max_deg": 117.3, "cart_tilt_limit_deg": 10.0})
    assert len(line) == 1 and line[0].startswith("the cart TIPPED: its body tilted past 10 deg at t = 0.09 s (117 deg")


def _two_bases(gap: np.ndarray, yaw: float = 0.0) -> SimpleNamespace:
    """Two Ridgebacks side by side, their centres `gap` (N,) m apart along y, the second turned by `yaw`."""
    n = gap.size
    x = np.zeros((n, 2, 10))
    x[:, 1, 1] = gap
    x[:, 1, 2] = yaw
    cfg = SimpleNamespace(dt=0.01, robot="ridgeback_iiwa")
    return SimpleNamespace(t=0.01 * np.arange(n), robot_x=x, base_twist=np.zeros((n, 2, 3)), config=cfg)


def test_two_bases_that_overlap_are_named_with_when_and_how_deep():
    from wholebody.push.report import _bases_overlap, _overlap_depth

    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert _overlap_depth(square, square + [0.7, 0.0]) == pytest.approx(0.3)
    assert _overlap_depth(square, square + [1.2, 0.0]) == 0.0
    apart = _two_bases(np.full(300, 0.893))  # the Ridgebacks are 0.793 m wide: 10 cm between them
    assert _bases_overlap(apart, math.inf) == []
    gap = np.full(300, 0.893)
    gap[100:200] = 0.493  # 30 cm into each other for a second
    (line,) = _bases_overlap(_two_bases(gap), math.inf)
    assert line.startswith("ROBOTS OVERLAP") and "for 1.00 s from t = 1.00 s, by up to 30 cm" in line
    assert _bases_overlap(_two_bases(gap), 0.5) == []  # after the loss: a failed push, not a plan
