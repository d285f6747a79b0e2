"""Robots known only by a profile file push the cart (kinematic plant): TIAGo from example-robot-data on
Traj. 2 (tracking, torque use, saturation), and a mobile manipulator without tuned push settings with one
and with two arms. The allocation keeps every joint torque within its URDF limit at every step."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import robots
from tests.robots.profile_files import UNTUNED_RIDGEBACK, tiago_profile, write_profile
from wholebody.push import TRUE_CART, PushConfig, run_push


def limits_hold(res) -> float:
    """Return the largest |tau| / limit of every joint of every arm at every step."""
    return float(np.max(np.abs(res.arm_torque) / res.effort_limit))


@pytest.fixture(scope="module")
def tiago(tmp_path_factory):
    return str(tiago_profile(tmp_path_factory.mktemp("tiago")))


def test_tiago_pushes_the_cart_on_traj2(tiago):
    res = run_push(PushConfig(robot=tiago, trajectory=2, duration=30.0))  # the paper's Traj. 2
    m = res.metrics
    assert res.arm_torque.shape[2] == 7 and res.robot_x.shape[2] == 10
    travelled = np.hypot(*(res.q_desired[-1, :2] - res.q_desired[0, :2]))
    assert travelled > 3.0 and m.tracking_rms_mm < 20.0 and m.grasp_error_max_m < 0.005
    # torque use: the loop's torques (rnea + J^T w) against TIAGo's URDF efforts, recomputed here
    r = robots.load(tiago)
    names = [f"arm_{i}_joint" for i in range(1, 8)]
    lim = np.array([r.model.effortLimit[r.model.joints[r.model.getJointId(n)].idx_v] for n in names])
    np.testing.assert_allclose(res.effort_limit, lim)
    assert limits_hold(res) <= 1.0 and m.arm_torque_limit_ratio == pytest.approx(limits_hold(res))
    assert m.arm_torque_limit_ratio > 0.3  # the push loads TIAGo's arm


def test_a_cart_too_heavy_for_tiago_saturates_and_says_which_limit_binds(tiago):
    heavy = replace(TRUE_CART, m=150.0, I=TRUE_CART.I * 7.5, sigma=150.0)  # a loaded hospital bed
    res = run_push(PushConfig(robot=tiago, trajectory=2, duration=12.0, true_params=heavy, initial_mass=150.0))
    m = res.metrics
    assert m.saturated_steps > 0 and m.saturation
    assert sum(v["total_s"] for v in m.saturation.values()) == pytest.approx(m.saturated_steps * 0.01)
    assert any("torque limit" in k and k.split()[1].startswith("arm_") for k in m.saturation)
    assert limits_hold(res) <= 1.0  # honoured, not reported after the fact


@pytest.mark.parametrize("arms", [1, 2])
def test_a_profile_without_tuned_push_settings_pushes_with_one_and_two_arms(tmp_path, capsys, arms):
    """The command line with a profile file: exit 0, tracking within 20 mm RMS, every torque within its limit."""
    import json

    from cartpush.cli.app import main

    joints = ", ".join(f'"iiwa_joint_{i}"' for i in range(1, 8))
    path = write_profile(tmp_path, UNTUNED_RIDGEBACK.format(urdf=robots.DATA_DIR / "ridgeback_iiwa.urdf", arm=joints))
    argv = ["push", "--robot", str(path), "--arms", str(arms), "--trajectory", "2", "--duration", "8", "--json"]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["tracking_rms_mm"] < 20.0 and out["arm_torque_limit_ratio"] <= 1.0
    assert isinstance(out["saturation"], dict)
