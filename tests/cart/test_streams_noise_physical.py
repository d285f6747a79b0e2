"""Unit tests of cart.streams (held rows, dropouts, stuck wrench), cart.noise_model (AR(1) fit) and cart.physical."""

from __future__ import annotations

import numpy as np
import pytest

from cart.logs import CartLog
from cart.noise_model import AR1Noise, fit_ar1
from cart.physical import constrained_fit, p_of_u
from cart.streams import split_streams


def _table(n_ft: int = 5000, ft_hz: float = 500.0, mocap_hz: float = 120.0) -> CartLog:
    t = np.arange(n_ft) / ft_hz
    t_m = np.arange(0.0, t[-1], 1.0 / mocap_hz)
    pose = np.column_stack([np.sin(0.3 * t_m), 0.5 * t_m, 0.1 * t_m]) + 1e-4 * np.random.default_rng(0).standard_normal(
        (len(t_m), 3)
    )
    idx = np.searchsorted(t_m, t, side="right") - 1
    idx[(t > 4.0) & (t < 4.5)] = np.searchsorted(t_m, 4.0, side="right") - 1  # a dropout: the pose held
    g = np.random.default_rng(1).standard_normal((n_ft, 3))
    return CartLog(t=t, q=pose[idx], gamma=g)


def test_a_held_pose_table_is_split_into_its_two_streams():
    st = split_streams(_table())
    assert st.multi_rate and 115 < st.pose_hz < 125 and 495 < st.wrench_hz < 505
    assert st.held_rows > 3000 and len(st.dropouts) == 1
    assert st.dropouts[0][0] == pytest.approx(4.0, abs=0.02) and st.dropouts[0][1] == pytest.approx(4.5, abs=0.02)


def test_a_frozen_wrench_is_a_stuck_sensor_but_a_single_rate_log_is_left_alone():
    log = _table()
    single = split_streams(
        CartLog(t=log.t, q=log.q + np.random.default_rng(3).normal(0, 1e-4, log.q.shape), gamma=log.gamma)
    )
    assert not single.multi_rate and single.held_rows == 0 and not single.stuck
    g = log.gamma.copy()
    g[1000:1600] = g[1000]
    st = split_streams(CartLog(t=log.t, q=log.q, gamma=g))
    assert len(st.stuck) == 1 and st.stuck[0][1] - st.stuck[0][0] == pytest.approx(1.2, abs=0.01)


@pytest.mark.parametrize("a", [0.0, 0.5, 0.9, 0.97])
def test_the_ar1_fit_recovers_level_and_colour(a):
    e = 2.0 * AR1Noise(1.0, a).unit_series(40000, seed=4)
    t = np.arange(len(e)) * 0.002
    fit = fit_ar1(e + 0.0 * t, 0.002)
    assert fit.sigma == pytest.approx(np.std(e), rel=0.05)
    assert fit.a == pytest.approx(a, abs=0.03)


def test_the_constrained_fit_is_physical_and_leaves_a_physical_estimate_alone():
    cov = np.diag([1.0, 0.5, 0.5, 0.2, 1.0, 1.0])
    good = p_of_u(np.array([np.log(30.0), 0.3, 0.05, np.log(2.0), 4.0, 1.0]))
    np.testing.assert_allclose(constrained_fit(good, cov), good, rtol=1e-8, atol=1e-8)
    bad = good.copy()
    bad[3] = 0.5 * (bad[1] ** 2 + bad[2] ** 2) / bad[0]  # J below m |c|^2: negative inertia about the CoM
    p = constrained_fit(bad, cov)
    m, a, b, j = p[:4]
    assert m > 0 and j - (a * a + b * b) / m > -1e-6 * j  # on the boundary at worst (I -> 0+), never below
    assert np.linalg.norm(p - bad) < np.linalg.norm(good - bad) + 1e-9  # the closest, not a far default
