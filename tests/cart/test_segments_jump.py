"""Tests of the momentum exchange seen in the pose (cart/segments.py: exchange_jump, exchange_shown)."""

from __future__ import annotations

import numpy as np

from cart import segments
from cart.logs import CartLog


def _straight_log(m0: float, m1: float, t_drop: float | None, seed: int = 0) -> CartLog:
    """Return a 100 Hz log of a cart pushed straight along a 30 deg heading by a varying force.

    ``m0`` kg before ``t_drop``, ``m1`` after (a load at rest put in: the forward momentum is shared, the speed
    drops with no force at the handle); None: no change. 0.5 mm pose noise, 1 N force noise.
    """
    rng = np.random.default_rng(seed)
    dt, th = 0.01, np.deg2rad(30.0)
    t = np.arange(0.0, 20.0, dt)
    f = 8.0 * np.sin(0.8 * t) + 5.0
    v, s, m = np.zeros_like(t), np.zeros_like(t), m0
    v[0] = 0.6
    for i in range(1, len(t)):
        if t_drop is not None and t[i - 1] < t_drop <= t[i]:
            v[i - 1] *= m0 / m1  # the momentum exchange
            m = m1
        v[i] = v[i - 1] + dt * (f[i - 1] - 2.0 * v[i - 1]) / m
        s[i] = s[i - 1] + dt * 0.5 * (v[i] + v[i - 1])
    q = np.column_stack([s * np.cos(th), s * np.sin(th), np.full_like(t, th)]) + 5e-4 * rng.standard_normal((len(t), 3))
    q[:, 2] = th
    fn = f + rng.standard_normal(len(t))
    gamma = np.column_stack([fn * np.cos(th), fn * np.sin(th), np.zeros_like(t)])
    return CartLog(t=t, q=q, gamma=gamma)


def test_the_speed_drop_of_a_put_in_is_the_momentum_exchange():
    # 40 -> 56 kg at 10 s: the jump is v (40 / 56 - 1) within a few of its std; the force's own acceleration is
    # taken out (the same log without the change shows no jump)
    log = _straight_log(40.0, 56.0, 10.0)
    v0, jump, sd, _ = segments.exchange_jump(log, 45.0, 10.03, 0.08)
    assert abs(jump - v0 * (40.0 / 56.0 - 1.0)) < 3.0 * sd + 0.02 * abs(jump)
    assert abs(jump) > 10.0 * sd
    _, jump0, sd0, _ = segments.exchange_jump(_straight_log(40.0, 40.0, None), 40.0, 10.03, 0.08)
    assert abs(jump0) < 4.0 * sd0


def test_the_exchange_is_shown_only_where_the_sides_masses_predict_it():
    log = _straight_log(40.0, 56.0, 10.0)
    assert segments.exchange_shown(log, 45.0, 10.0, (40.0, 56.0, 2.0), 0.08)  # z 2 on the sides alone: shown
    assert not segments.exchange_shown(log, 45.0, 10.0, (40.0, 42.5, 8.0), 0.08)  # the sides say 6 %, the pose 40 %
    assert not segments.exchange_shown(log, 45.0, 10.0, (56.0, 40.0, 2.0), 0.08)  # a lighter cart: no put-in
    plain = _straight_log(40.0, 40.0, None)
    assert not segments.exchange_shown(plain, 40.0, 10.0, (40.0, 56.0, 2.0), 0.08)  # no jump in the pose
