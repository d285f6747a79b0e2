"""The tip-over bound counts the inertia of the wrench the hands give, not of a demand they cannot give."""

from __future__ import annotations

import numpy as np
import pytest

from wholebody.contacts.support import tip_rows
from wholebody.push import PushConfig, build_controller
from wholebody.push import controller as controller_mod

PASSES = controller_mod.TIP_LOAD_PASSES


@pytest.fixture(scope="module")
def ctrl():
    # the estimate as it is (no std margin): the prior's 1-sigma would leave the CoM no hold on any edge
    return build_controller(PushConfig(trajectory=2, contact="fixed", tip_bound=True, tip_std_factor=0.0)).controller


def _allocate(ctrl, monkeypatch, passes: int, gamma: np.ndarray):
    monkeypatch.setattr(controller_mod, "TIP_LOAD_PASSES", passes)
    q, qd = np.zeros(3), np.array([0.8, 0.0, 0.3])  # in a left turn
    alloc = ctrl._allocate(q, qd, gamma, ctrl.config.true_params, ctrl.scheduler.y)
    given = controller_mod._body_to_generalized(q, alloc.gamma_achieved)
    rows, rhs, _ = tip_rows(
        ctrl.support, ctrl._cart_load(q, qd, given, ctrl.config.true_params), ctrl.allocator._points
    )
    return alloc, float(np.max(rows @ alloc.wrenches_ee.reshape(-1) - rhs))


def test_an_achievable_turn_is_allocated_as_asked(ctrl, monkeypatch):
    alloc, excess = _allocate(ctrl, monkeypatch, PASSES, np.array([5.0, 0.0, 5.0]))
    assert alloc.gamma_achieved[[0, 2]] == pytest.approx([5.0, 5.0], abs=1e-6)
    assert excess <= 1e-6


def test_a_turn_past_the_arms_gets_the_torque_the_cart_can_stand(ctrl, monkeypatch):
    # 40 N m asked: its yaw acceleration would swing the CoM out hard enough to tip the cart on paper, and the
    # bound under it forbids most of the sideways push that turns the cart; the cart only gets the achieved wrench
    gamma = np.array([5.0, 0.0, 40.0])
    once, _ = _allocate(ctrl, monkeypatch, 1, gamma)
    alloc, excess = _allocate(ctrl, monkeypatch, PASSES, gamma)
    assert alloc.gamma_achieved[2] > once.gamma_achieved[2] + 2.0
    assert excess <= 1e-6  # every wheel stays loaded under the acceleration the achieved wrench gives
