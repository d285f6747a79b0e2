"""Re-planned contacts move the hand smoothly: no single-sample joint-torque spikes (issue 20.2)."""

from __future__ import annotations

import numpy as np
import pytest

from wholebody.push import PushConfig, run_push


@pytest.fixture(scope="module")
def pair():
    """Traj. 2 (turns, so the plan moves), 12 s: re-planned contact vs a fixed one."""
    kw = dict(trajectory=2, duration=12.0)
    return run_push(PushConfig(contact="optimal", **kw)), run_push(PushConfig(contact="fixed", **kw))


def test_contact_slides_with_bounded_speed_and_acceleration(pair):
    opt, _ = pair
    cfg = opt.config
    y = opt.contact_y[:, 0]
    v = np.diff(y) / cfg.dt
    assert np.ptp(y) > 0.05  # the plan did move the contact
    assert np.abs(v).max() <= cfg.slide_speed + 1e-9
    assert np.abs(np.diff(v)).max() / cfg.dt <= cfg.slide_acceleration + 1e-6


def test_replanning_adds_no_joint_torque_spikes(pair):
    opt, fixed = pair
    step_opt = np.abs(np.diff(opt.arm_torque[:, 0], axis=0)).max()
    step_fixed = np.abs(np.diff(fixed.arm_torque[:, 0], axis=0)).max()
    assert step_opt <= 2.0 * step_fixed, (step_opt, step_fixed)
    assert opt.metrics.arm_torque_step_max_nm == pytest.approx(step_opt)
