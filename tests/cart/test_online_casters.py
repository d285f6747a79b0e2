"""Tests of the caster columns of the online regression (cart.online_casters, issue 27)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from cart.online_casters import CasterBank
from cart.online_estimator import make_online_estimator
from cart.online_regression import StateVariableFilter
from tests.cart.test_online_estimator import GUESS, MOCAP, TRUTH, _run, _sim


def _bank() -> CasterBank:
    return CasterBank(StateVariableFilter(2.0, 96))


def test_casters_trail_and_swing_round_on_a_reversal():
    """Pushed forward the casters trail (alpha -> 0); pushed back (with a slight turn: straight back is the
    swivel's unstable balance) they swing round by half a turn each."""
    bank = _bank()
    for _ in range(300):
        bank.raw_columns(0.5, 0.0, 0.01)
    assert np.allclose(np.sin(bank._alpha), 0.0, atol=1e-3)
    assert np.all(bank.half_turns < 0.05)
    for _ in range(300):
        bank.raw_columns(-0.5, 0.02, 0.01)
    assert np.allclose(np.cos(bank._alpha), -1.0, atol=1e-2)
    assert np.all(np.abs(bank.half_turns - 1.0) < 0.1)


@pytest.fixture(scope="module")
def turning_log():
    return _sim(40.0, True).measured


def _with_casters(log, geometry: int, resistance: np.ndarray):
    """Return the log whose measured wrench also overcomes the casters' resistance (geometry of the bank's grid)."""
    bank = _bank()
    gamma = log.gamma.copy()
    for k in range(1, len(log.t)):
        th = 0.5 * (log.q[k - 1, 2] + log.q[k, 2])
        vel = 0.5 * (log.qd[k - 1] + log.qd[k])
        v = math.cos(th) * vel[0] + math.sin(th) * vel[1]
        f, tau = bank.raw_columns(v, float(vel[2]), float(log.t[k] - log.t[k - 1]))[geometry] @ resistance
        gamma[k - 1] += (f * math.cos(th), f * math.sin(th), tau)
    return replace(log, gamma=gamma)


def test_the_columns_stay_off_on_a_cart_without_casters(turning_log):
    """Paper eq. 4 fits the log: the columns stay off and the estimate is the one without them."""
    with_c = _run(turning_log, make_online_estimator(turning_log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    without = make_online_estimator(turning_log.q[0], GUESS, MOCAP.measurement_std(), casters=False)
    without = _run(turning_log, without, 1, 3.0, 0.3)
    assert with_c.casters is not None and with_c.casters.active is None
    assert np.array_equal(with_c.regression.p, without.regression.p)


def test_the_columns_switch_on_and_remove_the_casters_bias(turning_log):
    """Casters that resist their swings (bearing friction 0.4 N m, rolling 3 N): the model without them misfits and
    its mass is off; the columns switch on and bring the mass within 2 %."""
    log = _with_casters(turning_log, 4, np.array([0.4, 0.0, 0.0, 3.0]))
    est = _run(log, make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    plain = _run(log, make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std(), casters=False), 1, 3.0, 0.3)
    assert est.casters is not None and est.casters.active is not None
    assert abs(est.params().m / TRUTH.m - 1.0) < 0.02
    assert abs(plain.params().m / TRUTH.m - 1.0) > 2.0 * abs(est.params().m / TRUTH.m - 1.0)
