"""Issue 30, physically consistent answers: a cart pushed straight says nothing of its CoM's forward coordinate.

The CoM's dx enters the regression only through the yaw rate (paper eq. 4: ``m dx`` multiplies ``-omega^2`` and
``omega v``). On a straight push the yaw rate is heading noise alone: an error in the variables that pulled dx to
0 with a std of a few cm (an independent simulator's 132 kg cart: dx 2.8 +- 6.8 cm for 58.8). The std now
carries that attenuation (`cart.identify._with_turn_attenuation`) and the report says dx is not identified.
"""

from __future__ import annotations

import numpy as np
import pytest

from cart.estimate_report import estimate_log
from cart.logs import CartLog
from tests.cart.test_streams_jumps import _push


def _straight(m: float = 60.0, dx: float = 0.5, dy: float = 0.1, seed: int = 0) -> CartLog:
    """A cart pushed straight along x at 100 Hz (speed 0.3 + 0.25 sin 0.9 t m/s): the forward row m vdot + c v,
    the yaw torque -m dy vdot that keeps it straight; pose noise 0.5 mm / 2 mrad, F/T noise 2 N / 0.3 N m."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 50.0, 0.01)
    v = 0.3 + 0.25 * np.sin(0.9 * t)
    vd = 0.225 * np.cos(0.9 * t)
    x = 0.3 * t - 0.25 / 0.9 * (np.cos(0.9 * t) - 1.0)
    q = np.column_stack([x, np.zeros_like(t), np.zeros_like(t)])
    q += rng.normal(0.0, 1.0, q.shape) * [5e-4, 5e-4, 2e-3]
    gamma = np.column_stack([m * vd + 4.0 * v, np.zeros_like(t), -m * dy * vd])
    gamma += rng.normal(0.0, 1.0, gamma.shape) * [2.0, 2.0, 0.3]
    return CartLog(t=t, q=q, gamma=gamma)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_straight_push_gives_mass_and_dy_and_says_dx_is_not_identified(seed):
    rep = estimate_log(_straight(seed=seed))
    assert rep.params.m == pytest.approx(60.0, rel=0.02)
    assert "dx" in rep.not_identified and "dy" not in rep.not_identified
    assert rep.to_dict()["com"][0] is None and rep.to_dict()["com"][1] == pytest.approx(0.1, abs=0.01)


def test_a_push_with_turns_still_identifies_dx():
    log, _ = _push()
    rep = estimate_log(log)
    assert "dx" not in rep.not_identified and "com" not in rep.not_identified
